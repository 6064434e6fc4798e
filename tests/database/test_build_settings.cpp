// SPDX-License-Identifier: Apache-2.0
// `db build`'s settings, the settings table's SettingScope::kBuild rows (drivenshape/
// settings_table.h): every row's flag is its key spelled with dashes, its default reads back to
// the default options, each refuses what it does not take with a message naming both
// spellings, and the values that stand for something (auto, off) set what DatabaseBuildOptions
// documents.

#include <gtest/gtest.h>

#include <string>

#include <drivenshape/error.h>
#include <drivenshape/settings_table.h>

#include "test_support.h"

namespace drivenshape {
namespace {

/// Sets the build setting `key` from the text a command line gives it.
void setBuildSetting(DatabaseBuildOptions& options, const std::string& key,
                     const std::string& text) {
  const Setting& setting = findSetting(key);
  setSetting(setting, options, parseSettingValue(setting, text));
}

/// The build setting's value in `options` as the text a command line gives.
std::string buildText(const Setting& setting, const DatabaseBuildOptions& options) {
  return formatSettingValue(setting, settingValue(setting, options));
}

TEST(BuildSettings, EveryFlagIsItsKeyAndEveryDefaultReadsBack) {
  const DatabaseBuildOptions defaults;
  ASSERT_GE(settingsOfScope(SettingScope::kBuild).size(), 10u);
  for (const Setting* setting : settingsOfScope(SettingScope::kBuild)) {
    std::string flag = std::string("--") + setting->key;
    for (char& c : flag) {
      c = c == '_' ? '-' : c;
    }
    EXPECT_EQ(flag, setting->flag);
    EXPECT_EQ(&findSetting(setting->key), setting);
    EXPECT_GT(std::string(setting->help).size(), 20u) << setting->key;
    DatabaseBuildOptions options;
    setBuildSetting(options, setting->key, buildText(*setting, defaults));
    for (const Setting* other : settingsOfScope(SettingScope::kBuild)) {
      EXPECT_EQ(buildText(*other, options), buildText(*other, defaults))
          << "setting " << setting->key << " to its default moved " << other->key;
    }
  }
}

TEST(BuildSettings, EachRefusesWhatItDoesNotTakeNamingBothSpellings) {
  for (const Setting* row : settingsOfScope(SettingScope::kBuild)) {
    const Setting& setting = *row;
    for (const char* text : {"", "x", "-1", "1e400", "2000000", "nan"}) {
      DatabaseBuildOptions options;
      try {
        setBuildSetting(options, setting.key, text);
        ADD_FAILURE() << setting.key << " took '" << text << "'";
      } catch (const Error& error) {
        const std::string message = error.what();
        EXPECT_EQ(error.code(), ErrorCode::kUsage);
        EXPECT_NE(message.find(setting.flag), std::string::npos) << message;
        EXPECT_NE(message.find(setting.key), std::string::npos) << message;
        EXPECT_NE(message.find(std::string("'") + text + "'"), std::string::npos) << message;
      }
    }
  }
  testing::expectThrows(
      [] {
        DatabaseBuildOptions options;
        setBuildSetting(options, "model_histroy", "30");
      },
      ErrorCode::kUsage, "model_histroy");
}

TEST(BuildSettings, WordsAndNumbersSetWhatTheOptionsDocument) {
  DatabaseBuildOptions o;
  setBuildSetting(o, "model_history", "30");
  EXPECT_EQ(o.model.historyFrames, 30);
  setBuildSetting(o, "model_history", "auto");
  EXPECT_EQ(o.model.historyFrames, kAutoHistory);
  setBuildSetting(o, "model_per_clip", "2.5");
  EXPECT_EQ(o.model.clipMixtureWeight, 2.5);
  setBuildSetting(o, "model_per_clip", "off");
  EXPECT_EQ(o.model.clipMixtureWeight, 0.0);
  setBuildSetting(o, "model_per_clip", "auto");
  EXPECT_EQ(o.model.clipMixtureWeight, kAutoClipMixture);
  setBuildSetting(o, "model", "none");
  EXPECT_FALSE(o.poseModel);
  // A choice is read as every setting's choices are, whatever the case (--weights QP).
  setBuildSetting(o, "model", "Pose");
  EXPECT_TRUE(o.poseModel);
  setBuildSetting(o, "model", "none");
  setBuildSetting(o, "verdict_level", "0.95");
  EXPECT_EQ(o.model.verdictLevel, 0.95);
  setBuildSetting(o, "duplicate_tolerance", "0.002");
  EXPECT_EQ(o.duplicateTolerance, 0.002);
  for (const auto& [key, text] :
       std::vector<std::pair<const char*, const char*>>{{"model_parts", "1"},
                                                        {"model_history", "121"},
                                                        {"verdict_level", "1"},
                                                        {"verdict_level", "0.4"},
                                                        {"model", "poses"},
                                                        {"count", "0"}}) {
    testing::expectThrows([&] { setBuildSetting(o, key, text); }, ErrorCode::kUsage, key);
  }
}

}  // namespace
}  // namespace drivenshape
