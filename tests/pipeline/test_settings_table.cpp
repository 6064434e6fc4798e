// SPDX-License-Identifier: Apache-2.0
// The settings table (drivenshape/settings_table.h): its rows, the one check of a value, the
// text a command line gives, and the settings it calls unused. The hash it derives is pinned
// in test_settings_hash.cpp; the Python keywords and the add-on's properties in
// tests/python/test_settings.py; docs/commands.md by the CTest settings_doc.

#include <array>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <drivenshape/bake.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/settings_table.h>

#include "test_support.h"

namespace drivenshape {
namespace {

TEST(SettingsTable, RowsAreUniqueAndHaveWhatTheToolsRead) {
  std::set<std::string> keys, flags;
  for (const Setting& setting : settingsTable()) {
    EXPECT_TRUE(keys.insert(setting.key).second) << setting.key;
    if (setting.flag != nullptr) {
      EXPECT_TRUE(flags.insert(setting.flag).second) << setting.flag;
      EXPECT_EQ(setting.valueName == nullptr, setting.type == SettingType::kBool) << setting.key;
    }
    EXPECT_NE(std::string(setting.help), "") << setting.key;
    EXPECT_EQ(setting.used == nullptr, std::string(setting.usedWhen).empty()) << setting.key;
    if (setting.type == SettingType::kObject) {
      continue;
    }
    // The default is the struct's, and passes the table's own check.
    ASSERT_TRUE(setting.scope == SettingScope::kBuild      ? hasBuildValue(setting)
                : setting.scope == SettingScope::kSimulate ? hasSimulateValue(setting)
                                                           : hasBakeValue(setting))
        << setting.key;
    EXPECT_NO_THROW(checkSettingValue(setting, defaultSettingValue(setting))) << setting.key;
  }
  EXPECT_EQ(formatSettingValue(defaultSettingValue(findSetting("exit_fade"))), "0.25");
  EXPECT_EQ(std::get<double>(defaultSettingValue(findSetting("skin_offset"))),
            EvaluatorSettings().skinOffset);
  EXPECT_EQ(std::get<int>(defaultSettingValue(findSetting("batch"))), BakeOptions().batchFrames);
  EXPECT_EQ(findSettingByKey("no_such_setting"), nullptr);
  testing::expectThrows([] { findSetting("no_such_setting"); }, ErrorCode::kUsage,
                        "no setting 'no_such_setting'");
}

TEST(SettingsTable, OneCheckOfAValueNamesTheSettingAndItsRange) {
  const Setting& fade = findSetting("exit_fade");
  EvaluatorSettings settings;
  setSetting(fade, settings, 0.3);
  EXPECT_EQ(settings.exitFade, 0.3);
  setSetting(fade, settings, 1);  // a whole number for a number
  EXPECT_EQ(settings.exitFade, 1.0);
  testing::expectThrows([&] { setSetting(fade, settings, -1.0); }, ErrorCode::kUsage,
                        "exit fade (exit_fade, --exit-fade) must be a number >= 0");
  EXPECT_EQ(settings.exitFade, 1.0);
  testing::expectThrows([&] { setSetting(fade, settings, std::string("x")); }, ErrorCode::kUsage,
                        "takes a number");
  testing::expectThrows([&] { setSetting(findSetting("max_weight_change"), settings, 1.5); },
                        ErrorCode::kUsage, "in [0, 1]");
  testing::expectThrows([&] { setSetting(findSetting("threads"), settings, -1); },
                        ErrorCode::kUsage, "0 = all cores");
  testing::expectThrows(
      [&] { setSetting(findSetting("blend"), settings, std::string("sideways")); },
      ErrorCode::kUsage, "takes world, local (got 'sideways')");
  setSetting(findSetting("weight_mode"), settings, std::string("Nearest"));
  EXPECT_EQ(settings.weightMode, WeightMode::kNearest);
  // A value set on the struct directly meets the same check in the Evaluator (checkSettings).
  settings.skinOffset = std::numeric_limits<double>::quiet_NaN();
  testing::expectThrows([&] { checkSettings(settings); }, ErrorCode::kUsage, "skin offset");
  BakeOptions options;
  options.batchFrames = 0;
  testing::expectThrows([&] { checkBakeSettings(options); }, ErrorCode::kUsage,
                        "batch (batch, --batch) must be a whole number >= 1");
}

TEST(SettingsTable, TextOfACommandLine) {
  EXPECT_EQ(std::get<double>(parseSettingValue(findSetting("exit_fade"), "0.25")), 0.25);
  EXPECT_EQ(std::get<int>(parseSettingValue(findSetting("batch"), "7")), 7);
  EXPECT_EQ(std::get<std::string>(parseSettingValue(findSetting("align"), "none")), "none");
  testing::expectThrows([] { parseSettingValue(findSetting("batch"), "1.5"); }, ErrorCode::kUsage,
                        "--batch) takes a whole number (got '1.5')");
  testing::expectThrows([] { parseSettingValue(findSetting("skin_offset"), "2mm"); },
                        ErrorCode::kUsage, "--skin-offset) takes a number (got '2mm')");
  EXPECT_EQ(formatSettingValue(0.1 + 0.2), "0.30000000000000004");
  EXPECT_EQ(formatSettingValue(0.002), "0.002");
  EXPECT_EQ(formatSettingValue(64), "64");
  EXPECT_EQ(formatSettingValue(false), "false");
}

// The layers' options and db build's are rows of the same table: in LayerOptions (and a bake's
// BakeOptions::layers) or DatabaseBuildOptions, checked by the same check, read from the same
// text, their words (auto) printed as a command line takes them.
TEST(SettingsTable, LayerAndBuildSettingsAreRowsOfTheSameTable) {
  const Setting& octaves = findSetting("wind_octaves");
  EXPECT_EQ(octaves.scope, SettingScope::kLayer);
  BakeOptions bake;
  setSetting(octaves, bake, 5);
  EXPECT_EQ(bake.layers.windOctaves, 5);
  EXPECT_EQ(std::get<int>(settingValue(octaves, bake)), 5);
  LayerOptions layers;
  testing::expectThrows([&] { setSetting(octaves, layers, 9); }, ErrorCode::kUsage,
                        "wind octaves (wind_octaves, --wind-octaves) must be a whole number <= 8 "
                        "(got 9; allowed: a whole number in [1, 8])");
  const Setting& direction = findSetting("wind_direction");
  EXPECT_EQ(formatSettingValue(defaultSettingValue(direction)), "1,0,0");
  setSetting(direction, layers, parseSettingValue(direction, "0,-1,0.5"));
  EXPECT_EQ(layers.windDirection, (std::array<double, 3>{0.0, -1.0, 0.5}));
  testing::expectThrows([&] { setSetting(direction, layers, std::string("1,0")); },
                        ErrorCode::kUsage, "--wind-direction) takes X,Y,Z");
  EXPECT_TRUE(hasLayerValue(findSetting("frames_per_second")));  // the wind's time

  const Setting& history = findSetting("model_history");
  EXPECT_EQ(history.scope, SettingScope::kBuild);
  EXPECT_FALSE(hasEvaluatorValue(history) || hasBakeValue(history) || hasLayerValue(history));
  EXPECT_EQ(formatSettingValue(history, defaultSettingValue(history)), "auto");
  DatabaseBuildOptions build;
  setSetting(history, build, parseSettingValue(history, "30"));
  EXPECT_EQ(build.model.historyFrames, 30);
  setSetting(history, build, parseSettingValue(history, "auto"));
  EXPECT_EQ(build.model.historyFrames, kAutoHistory);
  testing::expectThrows(
      [&] { parseSettingValue(history, "-1"); }, ErrorCode::kUsage,
      "must be a whole number >= 0 frames (0 = no history; got '-1'; allowed: auto or a "
      "whole number in [0, 120] frames)");
  testing::expectThrows([&] { setSetting(history, bake, 30); }, ErrorCode::kUsage,
                        "cannot be set from a value in EvaluatorSettings");
  EXPECT_EQ(settingsOfScope(SettingScope::kLayer).size(), 11u);  // --mix*, --wind-*
}

// simulate's settings (SimulationOptions) are rows of the same table too, in no other struct.
TEST(SettingsTable, SimulateSettingsAreRowsOfTheSameTable) {
  std::vector<std::string> keys;
  for (const Setting* setting : settingsOfScope(SettingScope::kSimulate)) {
    keys.emplace_back(setting->key);
    EXPECT_FALSE(hasEvaluatorValue(*setting) || hasBakeValue(*setting) || hasBuildValue(*setting) ||
                 hasLayerValue(*setting))
        << setting->key;
  }
  EXPECT_EQ(keys, (std::vector<std::string>{"warmup", "merge_gap", "goal_strength", "seam", "carry",
                                            "from_start"}));
  const Setting& goal = findSetting("goal_strength");
  SimulationOptions options;
  setSetting(goal, options, parseSettingValue(goal, "0.5"));
  EXPECT_EQ(options.goalStrength, 0.5);
  EXPECT_EQ(std::get<double>(settingValue(goal, options)), 0.5);
  setSetting(findSetting("from_start"), options, true);
  EXPECT_TRUE(options.fromStart);
  testing::expectThrows([&] { parseSettingValue(goal, "2"); }, ErrorCode::kUsage,
                        "goal strength (goal_strength, --goal-strength) must be a number <= 1");
  EXPECT_EQ(std::get<int>(defaultSettingValue(findSetting("warmup"))), kDefaultSimulationWarmup);
  options.carry = -1;
  testing::expectThrows([&] { checkSimulationSettings(options); }, ErrorCode::kUsage, "--carry");
  BakeOptions bake;
  testing::expectThrows([&] { setSetting(goal, bake, 0.5); }, ErrorCode::kUsage,
                        "cannot be set from a value in EvaluatorSettings");
}

std::vector<std::string> unusedKeys(const SettingsView& view,
                                    const std::vector<std::string>& given = {}) {
  std::vector<std::string> keys;
  for (const UnusedSetting& unused : unusedSettings(view, given)) {
    keys.emplace_back(unused.setting->key);
  }
  return keys;
}

TEST(SettingsTable, SettingsTheOthersLeaveUnusedAreRefusedOrWarnedAbout) {
  EvaluatorSettings settings;
  EXPECT_TRUE(unusedKeys({settings}).empty());
  settings.resolve = false;
  EXPECT_TRUE(unusedKeys({settings}).empty()) << "defaults are never unused";
  settings.exitFade = 0.3;
  settings.skinOffset = 0.004;
  EXPECT_EQ(unusedKeys({settings}), (std::vector<std::string>{"skin_offset", "exit_fade"}));
  const std::vector<std::string> warnings = refuseUnusedSettings(unusedSettings({settings}));
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_NE(warnings[1].find("exit fade '0.3' (exit_fade=0.3, --exit-fade 0.3)"), std::string::npos)
      << warnings[1];
  EXPECT_NE(warnings[1].find("resolution off"), std::string::npos) << warnings[1];

  // A value a tool was given counts even at its default: --blend local with --no-correct.
  settings = EvaluatorSettings();
  settings.correct = false;
  EXPECT_TRUE(unusedKeys({settings}).empty());
  EXPECT_EQ(unusedKeys({settings}, {"blend"}), std::vector<std::string>{"blend"});
  testing::expectThrows([&] { refuseUnusedSettings(unusedSettings({settings}, {"blend"})); },
                        ErrorCode::kUsage, "blend 'local'");
  settings.blend = BlendMode::kWorld;  // what runs without the correction: used
  EXPECT_TRUE(unusedKeys({settings}, {"blend"}).empty());

  // kAuto may become the QP: regions are used until the weights resolve to something else.
  settings = EvaluatorSettings();
  settings.regions = RegionSet();
  EXPECT_TRUE(unusedKeys({settings}).empty());
  settings.weightMode = WeightMode::kNearest;
  testing::expectThrows([&] { refuseUnusedSettings(unusedSettings({settings})); },
                        ErrorCode::kUsage, "regions");

  // Bake settings are judged only with the bake's options.
  BakeOptions options;
  options.temporalWarmup = 3;
  EXPECT_TRUE(unusedKeys({options.evaluator}).empty());
  EXPECT_EQ(unusedKeys({options.evaluator, &options}), std::vector<std::string>{"temporal_warmup"});
  options.evaluator.maxWeightChange = 0.1;
  EXPECT_TRUE(unusedKeys({options.evaluator, &options}).empty());
}

TEST(SettingsTable, JsonAndMarkdownListEveryRow) {
  const nlohmann::json table = nlohmann::json::parse(settingsTableJson());
  ASSERT_EQ(table.size(), settingsTable().size());
  // The evaluator's and the bake's settings in one table, the layers', db build's and
  // simulate's in theirs.
  const std::string markdown =
      settingsTableMarkdown() + settingsTableMarkdown(SettingScope::kLayer) +
      settingsTableMarkdown(SettingScope::kBuild) + settingsTableMarkdown(SettingScope::kSimulate);
  for (std::size_t i = 0; i < table.size(); ++i) {
    const Setting& setting = settingsTable()[i];
    EXPECT_EQ(table[i].at("key"), setting.key);
    EXPECT_EQ(table[i].at("hashed"), setting.hashed);
    EXPECT_NE(markdown.find(std::string("| `") + setting.key + "` |"), std::string::npos)
        << setting.key;
  }
  EXPECT_EQ(table[0].at("key"), "weight_mode");
  EXPECT_NE(markdown.find("\\|w_t - w_{t-1}\\|"), std::string::npos) << "pipes escaped";
}

}  // namespace
}  // namespace drivenshape
