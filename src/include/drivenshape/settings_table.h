// SPDX-License-Identifier: Apache-2.0
#pragma once

// The settings table: every setting of every tool declared once, with its names, type,
// default, range, unit, help, whether it enters the settings hash and which models use it:
// the evaluator's and the bake's, the layers' (mix, wind), `db build`'s and `simulate`'s. The
// command line's options and --help, the Python module's EvaluatorSettings, load_layers,
// build_database and plan_simulation keywords, the settings hash, the report's settings block and
// its schema, Evaluator:: describeSettings, the Blender add-on's properties and panels and the
// options tables of docs/commands.md all read it (docs/contributing.md: "Adding an evaluator
// setting").
//
//   for (const drivenshape::Setting& setting : drivenshape::settingsTable()) {
//     std::cout << setting.key << " = " << formatSettingValue(defaultSettingValue(setting));
//   }
//   drivenshape::EvaluatorSettings settings;
//   setSetting(findSetting("skin_offset"), settings, 0.003);  // checked: Error(kUsage) if < 0

#include <string>
#include <utility>
#include <variant>
#include <vector>

#include <drivenshape/bake_options.h>
#include <drivenshape/database.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/layers.h>

namespace drivenshape {

/// What a setting holds.
enum class SettingType {
  kBool,    ///< on or off; on the command line a flag that sets the other value (--no-resolve)
  kInt,     ///< a whole number
  kNumber,  ///< a real number
  kText,    ///< free text (vertex groups and ranges)
  kChoice,  ///< one of Setting::choices
  kObject   ///< loaded from a file (binding mask, regions, layers): in EvaluatorSettings the
            ///< loaded object, which each tool loads its own way; in BakeOptions the file's
            ///< path, where the bake has one (its value is that path, as text)
};

/// Where a setting lives: EvaluatorSettings (the Evaluator's; also BakeOptions::evaluator),
/// BakeOptions alone (what the bake adds around the Evaluator), LayerOptions (the layers: mix
/// and wind; also BakeOptions::layers), DatabaseBuildOptions (`db build`) or SimulationOptions
/// (`simulate`: the plan of the windows simulated after a bake and their splice).
enum class SettingScope { kEvaluator, kBake, kLayer, kBuild, kSimulate };

/// What becomes of a setting set away from its default that the other settings leave unused
/// (an exit fade without the resolution): refused (Error(kUsage)) or run with a warning.
enum class WhenUnused { kRefuse, kWarn };

/// A setting's value as tools pass it: kBool bool, kInt int, kNumber double (an int is
/// taken), kText, kChoice and kObject std::string (a choice's spelling, a file path).
using SettingValue = std::variant<bool, int, double, std::string>;

/// The settings a `used` test sees: the evaluator's and, for bake settings, the bake's.
struct SettingsView {
  const EvaluatorSettings& evaluator;
  const BakeOptions* bake = nullptr;
};

/// One row of the table. Plain data: rows are made once by settingsTable().
struct Setting {
  const char* key = "";    ///< "exit_fade": Python keyword and attribute, add-on property
  const char* label = "";  ///< "exit fade": in messages
  /// Command-line option ("--exit-fade"; for a kBool the flag that sets the non-default
  /// value, "--no-resolve"), nullptr where the command line does not take it.
  const char* flag = nullptr;
  const char* valueName = nullptr;  ///< in --help ("K"); nullptr for kBool flags
  SettingScope scope = SettingScope::kEvaluator;
  SettingType type = SettingType::kNumber;
  double minimum = 0;  ///< kInt and kNumber: the range, inclusive (checkSettingValue)
  double maximum = 0;
  /// kInt and kNumber: words that stand for a value outside the range or beside it
  /// (model_history's "auto" for kAutoHistory); a command line gives the word, never the number.
  std::vector<std::pair<std::string, double>> words;
  /// What the setting takes, in words, where the range does not say it all (with `accepts`).
  const char* takes = nullptr;
  /// The check beyond the range (model_parts: not 1); nullptr: the range is the check.
  bool (*accepts)(const SettingValue& value) = nullptr;
  const char* unit = "";             ///< "scene units", "frames", ... ("" for none)
  const char* zero = "";             ///< what 0 means ("off", "all cores"), or ""
  const char* help = "";             ///< one or more sentences, for --help, Python and the docs
  bool hashed = false;               ///< enters Evaluator::settingsHash (see settingsHash's layout)
  const char* reportKey = nullptr;   ///< the key in the report's settings, nullptr = none
  std::vector<std::string> choices;  ///< kChoice: the spellings
  /// False when `settings` certainly leave this setting unused; WeightMode::kAuto counts as
  /// every mode it can resolve to. nullptr: always used.
  bool (*used)(const SettingsView& settings) = nullptr;
  const char* usedWhen = "";  ///< `used` in words: "with the penetration resolution (resolve)"
  WhenUnused whenUnused = WhenUnused::kWarn;
  /// Access to the value (nullptr for kObject in EvaluatorSettings and for the other scopes).
  SettingValue (*getEvaluator)(const EvaluatorSettings&) = nullptr;
  void (*setEvaluator)(EvaluatorSettings&, const SettingValue&) = nullptr;
  SettingValue (*getBake)(const BakeOptions&) = nullptr;
  void (*setBake)(BakeOptions&, const SettingValue&) = nullptr;
  SettingValue (*getLayer)(const LayerOptions&) = nullptr;
  void (*setLayer)(LayerOptions&, const SettingValue&) = nullptr;
  SettingValue (*getBuild)(const DatabaseBuildOptions&) = nullptr;
  void (*setBuild)(DatabaseBuildOptions&, const SettingValue&) = nullptr;
  SettingValue (*getSimulate)(const SimulationOptions&) = nullptr;
  void (*setSimulate)(SimulationOptions&, const SettingValue&) = nullptr;
};

/// Every setting, in the order of the settings hash (then the ones it does not hash, then the
/// layers' and `db build`'s).
const std::vector<Setting>& settingsTable();
/// The settings of `scope`, in table order.
std::vector<const Setting*> settingsOfScope(SettingScope scope);
/// The setting named `key` ("exit_fade"), or nullptr.
const Setting* findSettingByKey(const std::string& key);
/// The same; Error(kUsage) naming the unknown key.
const Setting& findSetting(const std::string& key);

/// Whether `setting` has a value in EvaluatorSettings (kObject settings have none), in
/// BakeOptions (bake settings, evaluator settings with a value, file paths of kObject ones, the
/// layers' through BakeOptions::layers), in LayerOptions, in DatabaseBuildOptions or in
/// SimulationOptions.
bool hasEvaluatorValue(const Setting& setting);
bool hasBakeValue(const Setting& setting);
bool hasLayerValue(const Setting& setting);
bool hasBuildValue(const Setting& setting);
bool hasSimulateValue(const Setting& setting);

/// The value of `setting` in `settings` / `options`. Error(kUsage) where it has none there.
SettingValue settingValue(const Setting& setting, const EvaluatorSettings& settings);
SettingValue settingValue(const Setting& setting, const BakeOptions& options);
SettingValue settingValue(const Setting& setting, const LayerOptions& options);
SettingValue settingValue(const Setting& setting, const DatabaseBuildOptions& options);
SettingValue settingValue(const Setting& setting, const SimulationOptions& options);
/// The default (that of a default-constructed BakeOptions, or DatabaseBuildOptions for `db
/// build`'s, SimulationOptions for `simulate`'s).
SettingValue defaultSettingValue(const Setting& setting);
/// Sets `setting` to `value` after checkSettingValue. Error(kUsage) naming the setting for a
/// value of the wrong type or out of range, or a setting without a value there.
void setSetting(const Setting& setting, EvaluatorSettings& settings, const SettingValue& value);
void setSetting(const Setting& setting, BakeOptions& options, const SettingValue& value);
void setSetting(const Setting& setting, LayerOptions& options, const SettingValue& value);
void setSetting(const Setting& setting, DatabaseBuildOptions& options, const SettingValue& value);
void setSetting(const Setting& setting, SimulationOptions& options, const SettingValue& value);

/// The one check of a value, whichever tool set it: its type, a kChoice's spelling, a number's
/// range (finite; a word's value passes) and `accepts`. Error(kUsage) naming the setting
/// (label, key and flag), what it takes and the value.
void checkSettingValue(const Setting& setting, const SettingValue& value);
/// checkSettingValue on every value of `settings` (the Evaluator runs it) / of `options`'
/// bake settings (the bake runs it) / of the simulation's (the plan runs it).
void checkSettings(const EvaluatorSettings& settings);
void checkBakeSettings(const BakeOptions& options);
void checkSimulationSettings(const SimulationOptions& options);

/// Text to a value of `setting`'s type (command lines, farm job files, build_database's
/// keywords): one of its words, a number or a choice; Error(kUsage) naming the setting and
/// quoting the text for anything else, a number out of range included (checkSettingValue).
SettingValue parseSettingValue(const Setting& setting, const std::string& text);
/// "0.15", "true", "local", "" (shortest text that reads back to the same value).
std::string formatSettingValue(const SettingValue& value);
/// The same, or the word that stands for the value ("auto"): text parseSettingValue reads back.
std::string formatSettingValue(const Setting& setting, const SettingValue& value);

/// A setting that the other settings leave unused, and what to say about it.
struct UnusedSetting {
  const Setting* setting = nullptr;
  std::string message;  ///< names the setting, its value, when it is used and the settings
};
/// The settings of `view` that are set away from their defaults, or named in `given` (keys of
/// settings a tool was explicitly given, like a command line's flags), and unused there.
/// Evaluator settings are judged on `view.evaluator` (resolve kAuto first for the exact
/// answer); bake settings only when `view.bake` is set.
std::vector<UnusedSetting> unusedSettings(const SettingsView& view,
                                          const std::vector<std::string>& given = {});
/// Throws Error(kUsage) for the first of `unused` that is refused; returns the messages of
/// the others (warnings).
std::vector<std::string> refuseUnusedSettings(const std::vector<UnusedSetting>& unused);

/// The bake report's entries for the bake settings and the files of kObject settings (JSON
/// object text), beside Evaluator::describeSettings's.
std::string describeBakeSettings(const BakeOptions& options);

/// The table as JSON text: an array of objects (key, label, flag, scope, type, default,
/// minimum, maximum, words, takes, unit, zero, choices, help, hashed, report_key, report,
/// used_when, when_unused, addon: what scripts/generate_from_settings.py makes the add-on's
/// properties and the report schema's settings from).
std::string settingsTableJson();
/// The table as the Markdown table of docs/commands.md ("Settings": the evaluator's and the
/// bake's settings).
std::string settingsTableMarkdown();
/// The layers' (SettingScope::kLayer), `db build`'s (kBuild) or `simulate`'s (kSimulate)
/// options as a Markdown table.
std::string settingsTableMarkdown(SettingScope scope);

}  // namespace drivenshape
