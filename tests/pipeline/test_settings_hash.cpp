// SPDX-License-Identifier: Apache-2.0
// The settings hash is a file-format contract: the bake writes it into every EXR header
// (dsSettingsHash, which --skip-existing compares) and into its report. Issue 27 moved the
// settings into one table and derived the hash from its rows; these values pin the hash as it
// was before, so that a resume after upgrading does not bake every frame again.
//
// Where the values come from: this test was first built against main at commit 9921612
// (before the settings table existed; the commit that adds it changes nothing else) and the
// values were printed there by that commit's Evaluator (the test prints what it measures; they
// were the same on 1 and 2 cores). Every later commit must reproduce them.
// The library version is part of the hash, so every value here is the hash as version 0.1.0
// computes it (Evaluator::settingsHashOfVersion): the pins keep their source, main at 9921612,
// across version bumps; one test checks that this build's own version gives other values.

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <drivenshape/binding.h>
#include <drivenshape/database.h>
#include <drivenshape/device.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/layers.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/regions.h>
#include <drivenshape/settings_table.h>
#include <drivenshape/version.h>

#include "hash.h"

#include "test_support.h"

namespace drivenshape {
namespace {

std::string data(const std::string& name) {
  return std::string(DS_TEST_DATA_DIR) + "/" + name;
}

/// A 10-shape database of the bundled sleeve sample, built in process: without the pose model
/// (the default weights resolve to the QP, as for every database before 0.2) or with it.
Database buildSample(bool poseModel) {
  return testing::buildSleeveDatabase(poseModel);
}

/// The version whose hashes the tests below pin (the hashes main printed at 9921612).
constexpr const char* kPinnedVersion = "0.1.0";

struct Pinned {
  const char* name;
  std::function<void(EvaluatorSettings&)> change;
  const char* hash;        ///< Evaluator::settingsHash()
  const char* outputHash;  ///< settingsHash({1024, 8, 64}): the bake's defaults
};

TEST(SettingsHash, IsTheHashOfMainBeforeTheSettingsTable) {
  const Database db = buildSample(false);
  std::unique_ptr<Device> host = makeHostDevice();
  const OutputHashFields bakeDefaults{1024, 8, 64};
  const OutputHashFields otherOutput{512, 3, 7};
  const std::vector<Pinned> pinned = {
      {"defaults", [](EvaluatorSettings&) {}, "9c0417b7c46f5225", "cf8567bbbd041189"},
      {"weights nearest", [](EvaluatorSettings& s) { s.weightMode = WeightMode::kNearest; },
       "e003a5a0d2cb14ba", "fa85b8b5fdfaef26"},
      {"weights bind", [](EvaluatorSettings& s) { s.weightMode = WeightMode::kBind; },
       "d399e4fb80e0c0c3", "291889ed0c5ff86f"},
      {"no correction",
       [](EvaluatorSettings& s) {
         s.correct = false;
         s.blend = BlendMode::kWorld;
       },
       "6b164d426253de5b", "42bd5168d43e528f"},
      {"align none", [](EvaluatorSettings& s) { s.align = AlignMode::kNone; }, "bd4500e4a78d0dfd",
       "1a8aadb9b1ce7491"},
      {"align rigid-all", [](EvaluatorSettings& s) { s.align = AlignMode::kRigidAll; },
       "2f5bad1b645a35d1", "dbce869e25afe725"},
      {"align group", [](EvaluatorSettings& s) { s.alignGroup = "0-500"; }, "8da89f45e8f6a900",
       "aeda3298e016bf34"},
      {"blend world", [](EvaluatorSettings& s) { s.blend = BlendMode::kWorld; }, "c885d8d98bbaf3f4",
       "a7cebd4dbdc1f858"},
      {"no resolution", [](EvaluatorSettings& s) { s.resolve = false; }, "be3f55915cc332f0",
       "550c137cefdffc64"},
      {"skin offset", [](EvaluatorSettings& s) { s.skinOffset = 0.004; }, "71104b86377685d5",
       "afbacc83c1b7abd9"},
      {"exit fade off", [](EvaluatorSettings& s) { s.exitFade = 0.0; }, "a5dd5c3a8b1db991",
       "b52124a3b145328d"},
      {"exit fade 0.3", [](EvaluatorSettings& s) { s.exitFade = 0.3; }, "9052ce3a97ab4a55",
       "58fb3ca127bf4bd9"},
      {"max weight change", [](EvaluatorSettings& s) { s.maxWeightChange = 0.1; },
       "9b88d48fa2061e5a", "ab394a2b76b3bbee"},
      {"binding mask",
       [&db](EvaluatorSettings& s) {
         s.bindingMask =
             readBindingMask(data("golden/bind_mask.json"), db.driverMesh, db.drivenMesh);
       },
       "04b4bf3e780cefe5", "9bb8b0a40aebe249"},
      {"regions",
       [&db](EvaluatorSettings& s) {
         s.regions = readRegions(data("golden/regions.json"), db.driverMesh, db.drivenMesh);
       },
       "d4d6156e88ef814a", "0e47c7314ee4509e"},
      {"wind",
       [&db](EvaluatorSettings& s) {
         LayerOptions layers;
         layers.windAmplitude = 0.01;
         s.layers = loadLayers(layers, db.drivenMesh);
       },
       "96d73d2fcd81ff4f", "311a90b3a97d04ce"},
  };
  for (const Pinned& p : pinned) {
    EvaluatorSettings settings;
    // 0.2 moves cloth the nearest way out by default, which changes the output (and so the
    // hash) of every bake with the resolution; along the normal, the hash is main's.
    settings.resolveDirection = ResolveDirection::kNormal;
    // The defaults limit strain and fade the exit at 0.25 since issue 43; off and at 0.15, the
    // hash is main's.
    settings.strainLimit = 0.0;
    settings.exitFade = 0.15;
    p.change(settings);
    const Evaluator evaluator(db, settings, *host);
    const std::string hash = hashToHex(evaluator.settingsHashOfVersion(kPinnedVersion));
    const std::string output =
        hashToHex(evaluator.settingsHashOfVersion(kPinnedVersion, &bakeDefaults));
    std::printf("  %-20s %s %s\n", p.name, hash.c_str(), output.c_str());
    EXPECT_EQ(hash, p.hash) << p.name;
    EXPECT_EQ(output, p.outputHash) << p.name << " with the bake's output fields";
    if (settings.maxWeightChange > 0) {
      // With the temporal bound the warm-up and the batch size enter the hash too.
      EXPECT_EQ(hashToHex(evaluator.settingsHashOfVersion(kPinnedVersion, &otherOutput)),
                "a4bfb71eb709f2a0")
          << p.name;
    }
  }
}

// The nearest way out, the default since 0.2, changes the hash of a bake with the resolution
// (a resume bakes such frames again) and leaves the hash of one without it.
TEST(SettingsHash, TheResolveDirectionEntersTheHashOnlyWithTheResolution) {
  const Database db = buildSample(false);
  std::unique_ptr<Device> host = makeHostDevice();
  for (const bool resolve : {true, false}) {
    EvaluatorSettings nearest;
    nearest.resolve = resolve;
    EvaluatorSettings normal = nearest;
    normal.resolveDirection = ResolveDirection::kNormal;
    const std::uint64_t a = Evaluator(db, nearest, *host).settingsHash();
    const std::uint64_t b = Evaluator(db, normal, *host).settingsHash();
    if (resolve) {
      EXPECT_NE(a, b) << "with the resolution";
    } else {
      EXPECT_EQ(a, b) << "without the resolution";
    }
  }
}

// The defaults on a database with the pose model (what `db build` makes): weights model. Since
// 0.2.0 the database also holds the verdict's calibration, which its content hash (and so the
// settings hash) takes in; without it (level 0: a database of before) the hash is main's.
TEST(SettingsHash, IsTheHashOfMainBeforeTheSettingsTableWithThePoseModel) {
  const Database db = buildSample(true);
  ASSERT_GT(db.poseModel.verdictLevel, 0.0);
  Database before = db;
  before.poseModel.verdictLevel = 0.0;
  before.poseModel.verdictMargin = 0.0;
  std::unique_ptr<Device> host = makeHostDevice();
  EvaluatorSettings normal;  // 0.1's resolution, no strain limit, fade 0.15 (see above)
  normal.resolveDirection = ResolveDirection::kNormal;
  normal.strainLimit = 0.0;
  normal.exitFade = 0.15;
  const Evaluator evaluator(before, normal, *host);
  ASSERT_EQ(evaluator.settings().weightMode, WeightMode::kModel);
  const OutputHashFields bakeDefaults{1024, 8, 64};
  const std::string hash = hashToHex(evaluator.settingsHashOfVersion(kPinnedVersion));
  const std::string output =
      hashToHex(evaluator.settingsHashOfVersion(kPinnedVersion, &bakeDefaults));
  std::printf("  pose model defaults   %s %s\n", hash.c_str(), output.c_str());
  EXPECT_EQ(hash, "295dc96bec57c31e");
  EXPECT_EQ(output, "f55a50a5393e1e72");
  const Evaluator calibrated(db, normal, *host);
  EXPECT_NE(hashToHex(calibrated.settingsHashOfVersion(kPinnedVersion)), hash)
      << "the verdict is part of the database";
}

// The version string is part of the hash: this build's hash is the one of its own version, and
// another version's outputs never match it (a resume after upgrading bakes them again).
TEST(SettingsHash, TheLibraryVersionEntersTheHash) {
  const Database db = buildSample(false);
  std::unique_ptr<Device> host = makeHostDevice();
  const Evaluator evaluator(db, EvaluatorSettings{}, *host);
  const OutputHashFields bakeDefaults{1024, 8, 64};
  EXPECT_EQ(evaluator.settingsHash(), evaluator.settingsHashOfVersion(kVersion));
  EXPECT_EQ(evaluator.settingsHash(bakeDefaults),
            evaluator.settingsHashOfVersion(kVersion, &bakeDefaults));
  EXPECT_NE(evaluator.settingsHashOfVersion("0.1.0"), evaluator.settingsHashOfVersion("0.1.1"));
}

/// A value of `setting` other than its default that the sample's settings can run.
SettingValue otherValue(const Setting& setting) {
  const SettingValue value = defaultSettingValue(setting);
  switch (setting.type) {
    case SettingType::kBool:
      return !std::get<bool>(value);
    case SettingType::kInt:
      return std::get<int>(value) + 1;
    case SettingType::kNumber: {
      const double number = std::get<double>(value);
      return std::isinf(setting.maximum) ? 2 * number + 0.001 : (number + setting.maximum) / 2;
    }
    case SettingType::kChoice:
      // The sample's database has no pose model: "nearest", not "model" (nor "qp", which is
      // what "auto" resolves to there).
      return std::string(setting.key) == "weight_mode"                 ? std::string("nearest")
             : setting.choices.front() == std::get<std::string>(value) ? setting.choices.back()
                                                                       : setting.choices.front();
    default:
      return std::string("0-500");  // the align group, the one kText setting
  }
}

// The table's `hashed` is what the hash does: changing a hashed setting changes the bake's
// hash, changing any other leaves it. (kObject settings: see the pinned values above.)
TEST(SettingsHash, EveryHashedSettingOfTheTableChangesItAndNoOtherDoes) {
  const Database db = buildSample(false);
  std::unique_ptr<Device> host = makeHostDevice();
  const auto hashOf = [&](const BakeOptions& o) {
    const Evaluator evaluator(db, o.evaluator, *host);
    return evaluator.settingsHash(OutputHashFields{o.exrWidth, o.temporalWarmup, o.batchFrames});
  };
  int checked = 0;
  for (const Setting& setting : settingsTable()) {
    // The layers' own options are hashed as the layers row loads them (pinned above), the
    // database build's as the database's content hash.
    const bool evaluatorOrBake =
        setting.scope == SettingScope::kEvaluator || setting.scope == SettingScope::kBake;
    if (setting.type == SettingType::kObject || !evaluatorOrBake) {
      continue;
    }
    BakeOptions base;
    // The warm-up and the batch decide which frame bounds which only with the temporal bound.
    const std::string key = setting.key;
    if (key == "temporal_warmup" || key == "batch") {
      base.evaluator.maxWeightChange = 0.1;
    }
    // The iterations change the cloth only with the strain limit on.
    if (key == "strain_iterations") {
      base.evaluator.strainLimit = 0.05;
    }
    BakeOptions changed = base;
    setSetting(setting, changed, otherValue(setting));
    EXPECT_EQ(hashOf(changed) != hashOf(base), setting.hashed)
        << key << " = " << formatSettingValue(otherValue(setting));
    ++checked;
  }
  EXPECT_GE(checked, 15);
}

}  // namespace
}  // namespace drivenshape
