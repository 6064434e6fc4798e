// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <string>
#include <vector>

namespace drivenshape::cli {

/// `drivenshape simulate`: simulates the frames a bake's verdict flags in Blender, a window
/// at a time warm-started from the bake, and splices the windows into the baked sequence
/// (drivenshape/simulation.h). Errors propagate as drivenshape::Error to main's single catch.
int runSimulate(const std::vector<std::string>& args);

}  // namespace drivenshape::cli
