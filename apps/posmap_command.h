// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <string>
#include <vector>

namespace drivenshape::cli {

/// `drivenshape posmap`: position maps (UV-space P, A, optional N) of a mesh for every frame
/// of a cache. Parses its words, calls the library (PositionMapWriter) and returns the exit
/// code; errors propagate as drivenshape::Error to main's single catch.
int runPosmap(const std::vector<std::string>& args);

}  // namespace drivenshape::cli
