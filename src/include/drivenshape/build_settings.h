// SPDX-License-Identifier: Apache-2.0
#pragma once

// The database build's settings: each `db build` setting declared once, with its command-line
// flag, Python keyword, help, default and the one check of its value. `drivenshape db build`'s
// options and --help and the Python module's build_database keywords both read this table, so
// a setting added here reaches both spelled the same (the flag is the key with dashes). The
// inputs that are not settings (meshes, caches, candidate and added frames, more clips, a rig)
// stay arguments of their own.
//
//   drivenshape::DatabaseBuildOptions options;
//   drivenshape::setBuildSetting(options, "model_history", "30");  // Error(kUsage) if refused

#include <string>
#include <vector>

#include <drivenshape/database.h>

namespace drivenshape {

/// One row of the table. Plain data: rows are made once by buildSettingsTable().
struct BuildSetting {
  const char* key = "";        ///< "model_history": the Python keyword
  const char* flag = "";       ///< "--model-history": the command-line option
  const char* valueName = "";  ///< "N": in --help
  const char* help = "";       ///< for --help, the Python docstring and the docs
  /// Sets the setting (`self`, this row) in `options` from its text (a command line's word;
  /// Python passes the value as text). Error(kUsage) naming the flag and the key, with what
  /// they take, for text it refuses.
  void (*set)(const BuildSetting& self, DatabaseBuildOptions& options,
              const std::string& text) = nullptr;
  /// The setting's value in `options` as text that set() reads back (the default's, for a
  /// default-constructed DatabaseBuildOptions).
  std::string (*get)(const DatabaseBuildOptions& options) = nullptr;
};

/// Every `db build` setting, in the order of `db build --help`.
const std::vector<BuildSetting>& buildSettingsTable();
/// The setting named `key` ("model_history"); Error(kUsage) naming the unknown key and the
/// known ones.
const BuildSetting& findBuildSetting(const std::string& key);
/// Sets the setting named `key` from `text` (BuildSetting::set).
void setBuildSetting(DatabaseBuildOptions& options, const std::string& key,
                     const std::string& text);

}  // namespace drivenshape
