// SPDX-License-Identifier: Apache-2.0
#pragma once

// The settings table's rows with what only the library does with them: how each setting enters
// the settings hash and the report, how the report schema and the Blender add-on show it.
// Declared with the rest of the row in settings_table.cpp.

#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include <drivenshape/settings_table.h>

#include "hash.h"

namespace drivenshape::pipeline {

class Model;

/// What a row hashes: the evaluator's model (its validated settings, with the weight mode
/// resolved, and what they select: the mask, the alignment's vertices and weights, the blend)
/// and, for a bake, the writer's fields.
struct HashInput {
  const Model& model;
  const OutputHashFields* output = nullptr;
};

/// An entry a row writes into the report's settings, for its schema
/// (docs/schemas/bake_report.schema.json, written by scripts/generate_from_settings.py).
struct ReportEntry {
  const char* path = "";  ///< "exit_fade"; a nested one "layers.wind.octaves"
  /// Its JSON schema where the row's type, range and choices do not give it (an array, a
  /// value the writer resolves), as JSON text; nullptr: from the row.
  const char* schema = nullptr;
  bool required = true;  ///< whether every report (or every enclosing object) holds it
};

/// One choice of a kChoice setting in the add-on's menu.
struct AddonChoice {
  const char* choice = "";       ///< the table's spelling ("rigid-all")
  const char* name = "";         ///< the menu's ("Rigid (All)")
  const char* description = "";  ///< its tooltip
};

/// How the Blender add-on shows a setting (apps/blender/drivenshape_blender/
/// settings_generated.py, from this): a property of the scene's DrivenShape settings, a row of
/// one of its panels, and the argument it passes to the module. No panel: not in the add-on.
struct AddonView {
  const char* panel =
      nullptr;  ///< the sub-panel: "settings", "collision", "device", "coverage", "build"
  const char* name =
      nullptr;  ///< the property's name, Title Case; nullptr: the label's words capitalised
  const char* text = nullptr;      ///< the panel row's shorter text; nullptr: the name
  const char* heading = nullptr;   ///< a checkbox's heading in the panel ("Collision")
  const char* property = nullptr;  ///< the property where it is not the key (.blend files keep it)
  const char* activeWith = nullptr;  ///< the key of a kBool setting whose off greys the row out
  const char* checkbox = nullptr;    ///< a two-choice setting as a checkbox: the choice it means on
  double softMaximum = std::numeric_limits<double>::quiet_NaN();  ///< the slider's end
  int precision = -1;                                             ///< digits shown (-1: Blender's)
  double step = 0;  ///< Blender's step (1/100 of a unit; 0: Blender's)
  /// The menu of a kChoice, in order: an item's place is the number .blend files store, so
  /// append, never reorder.
  std::vector<AddonChoice> choices;
  /// The add-on's default where it is not the table's, and why (it must differ).
  std::optional<SettingValue> defaultValue;
  const char* defaultWhy = "";
};

struct SettingRow {
  Setting setting;
  /// The entries it writes in the report's settings: `reportKey` first, then any a describe
  /// function adds (see ReportEntry).
  std::vector<ReportEntry> report;
  /// report(): the choice the writer resolves before reporting ("auto"), not in the report.
  const char* reportResolves = nullptr;
  AddonView addon;
  /// Adds the setting to the hash, in table order, before the library version.
  void (*hash)(const HashInput& input, Hasher& hasher) = nullptr;
  /// A block after the version (the layers, added to the hash in 0.1 that way): the hash so far
  /// in, the hash continued out.
  std::uint64_t (*hashAfterVersion)(const HashInput& input, std::uint64_t value) = nullptr;
  /// Its entries in Evaluator::describeSettings; nullptr: `reportKey` = its value, if any.
  void (*describe)(const Model& model, nlohmann::json& settings) = nullptr;
  /// Its entries in the bake report's settings (bake settings, files of kObject settings).
  void (*describeBake)(const BakeOptions& options, nlohmann::json& settings) = nullptr;
};

/// The rows of settingsTable(), in the same order.
const std::vector<SettingRow>& settingRows();

/// The settings hash of Evaluator::settingsHash up to the stages' own additions (docs/formats.md,
/// "Point-cache EXR": a resume compares it, so its layout is fixed): the database's content hash,
/// every hashed row in table order, the library version (`version`, this build's kVersion but for
/// Evaluator::settingsHashOfVersion), then the rows hashed after it.
std::uint64_t hashSettings(const Model& model, const OutputHashFields* output, const char* version);
/// Every evaluator setting's entries of the report (before the stages add theirs).
void describeSettings(const Model& model, nlohmann::json& settings);

}  // namespace drivenshape::pipeline
