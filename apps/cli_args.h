// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <initializer_list>
#include <map>
#include <string>
#include <vector>

#include <drivenshape/frames.h>

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

 private:
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
};

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
