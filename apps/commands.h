// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <string>
#include <vector>

namespace drivenshape::cli {

/// Each command parses its words, calls the library and returns the process exit code
/// (0 on success). Errors propagate as drivenshape::Error to main's single catch.
int runDevices(const std::vector<std::string>& args);
int runInfo(const std::vector<std::string>& args);
int runDbBuild(const std::vector<std::string>& args);
int runBake(const std::vector<std::string>& args);

/// Checks the words of a bake's command line (what follows `drivenshape bake`) as `bake` reads
/// them, before it opens any file: its parser (an unknown option, a missing value, a stray word)
/// and every value it checks there (numbers and their ranges, the settings and the settings they
/// need, layers, farm chunks, position maps). Throws Error(kUsage) with the bake's message.
void checkBakeArguments(const std::vector<std::string>& args);

}  // namespace drivenshape::cli
