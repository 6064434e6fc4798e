// SPDX-License-Identifier: Apache-2.0
#pragma once

// The settings table's rows with what only the library does with them: how each setting enters
// the settings hash and the report. Declared with the rest of the row in settings_table.cpp.

#include <cstdint>
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

struct SettingRow {
  Setting setting;
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
