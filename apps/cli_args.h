// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <initializer_list>
#include <map>
#include <string>
#include <vector>

#include <drivenshape/bake.h>
#include <drivenshape/frames.h>
#include <drivenshape/settings_table.h>

namespace drivenshape::cli {

/// A small declarative parser for `--name value` and `--flag` options of one command.
/// Unknown flags, missing values, missing required options and bad numbers throw
/// Error(kUsage) naming the flag and pointing at --help.
class ArgParser {
 public:
  ArgParser(std::string usage, std::string summary);

  /// A value option: `--name VALUE`. `defaultValue` is shown in --help.
  ArgParser& option(const std::string& name, const std::string& valueName, const std::string& help,
                    const std::string& defaultValue = "", bool required = false);
  /// A repeatable option of `words` values: `--name A B`, given any number of times (all()).
  /// `valueName` names the words in --help, e.g. "DRIVER DRIVEN".
  ArgParser& repeated(const std::string& name, const std::string& valueName, int words,
                      const std::string& help);
  /// A boolean flag: `--name`.
  ArgParser& flag(const std::string& name, const std::string& help);
  /// Options for settings of the settings table (drivenshape/settings_table.h): `keys`, or
  /// every setting the command line takes (in table order) when `keys` is empty. Their flags,
  /// value names, help and defaults come from the table; readSettings() reads them.
  ArgParser& settings(std::initializer_list<const char*> keys = {});
  /// The same for every setting of `scope` that the command line takes: the layers'
  /// (SettingScope::kLayer), `db build`'s (kBuild) or `simulate`'s (kSimulate).
  ArgParser& settings(SettingScope scope);
  /// Extra text printed after the options in --help.
  ArgParser& epilog(const std::string& text);
  /// Accept `count` positional arguments described by `names` (e.g. "FILE").
  ArgParser& positional(const std::string& names, int count);

  /// Parses args (the words after the command). Returns false if --help was asked for.
  bool parse(const std::vector<std::string>& args);
  std::string help() const;

  bool has(const std::string& name) const;
  std::string get(const std::string& name) const;
  int getInt(const std::string& name, int minimum) const;
  double getDouble(const std::string& name, double minimum) const;
  /// Every use of a repeated option, in the order given: its words each time.
  std::vector<std::vector<std::string>> all(const std::string& name) const;
  const std::vector<std::string>& positionals() const { return mPositionals; }
  /// The settings declared with settings(), in order.
  const std::vector<const Setting*>& declaredSettings() const { return mSettings; }

 private:
  ArgParser& declareSettings(const std::vector<const Setting*>& chosen);

  struct Spec {
    std::string valueName;  // empty for flags
    std::string help;
    std::string defaultValue;
    bool required = false;
    int words = 1;  // values per use; repeated options only
    bool repeated = false;
  };
  std::string mUsage;
  std::string mSummary;
  std::string mEpilog;
  std::string mPositionalNames;
  int mPositionalCount = 0;
  std::vector<std::string> mOrder;
  std::map<std::string, Spec> mSpecs;
  std::map<std::string, std::string> mValues;
  std::map<std::string, std::vector<std::vector<std::string>>> mRepeated;
  std::vector<std::string> mPositionals;
  std::vector<const Setting*> mSettings;
};

/// Sets each settings option given on the command line through the settings table, which
/// checks the value, and refuses a given setting that the others leave unused (--blend local
/// with --no-correct): Error(kUsage) naming the flag. Unused values that are only warned about
/// are left to the library, which warns when it runs.
void readSettings(const ArgParser& parser, BakeOptions& options);
/// The same for commands that take evaluator settings only.
void readSettings(const ArgParser& parser, EvaluatorSettings& settings);
/// The same for the layers' settings (SettingScope::kLayer), `db build`'s (kBuild) and
/// `simulate`'s (kSimulate).
void readSettings(const ArgParser& parser, LayerOptions& options);
void readSettings(const ArgParser& parser, DatabaseBuildOptions& options);
void readSettings(const ArgParser& parser, SimulationOptions& options);

/// `path` made absolute and normalised, for messages and summaries (unchanged if that fails).
std::string absolute(const std::string& path);

/// The files `options` name on the command line (those given), for checkDistinctPaths. With
/// `sequences`, a value with a frame token is a sequence (a cache pattern), else every value is
/// one file.
std::vector<NamedPath> givenPaths(const ArgParser& parser,
                                  std::initializer_list<const char*> options,
                                  bool sequences = false);

/// Creates the missing folders of the output files `paths` (createOutputFolders), as Houdini's
/// ROPs do, and names each one it created on stderr unless `quiet`.
void createOutputFoldersFor(const std::vector<std::string>& paths, bool quiet);

}  // namespace drivenshape::cli
