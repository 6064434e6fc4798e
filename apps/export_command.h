// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <string>
#include <vector>

namespace drivenshape::cli {

/// `drivenshape export`: guides for simulation. Writes frames of a cache (a bake's EXR sequence
/// or any PC2) as one PC2 point cache (goal or pin targets for Blender or Maya) and/or
/// the first frame as an OBJ with the rest mesh's faces, UVs and groups (an initial drape).
/// Errors propagate as drivenshape::Error to main's single catch.
int runExport(const std::vector<std::string>& args);

}  // namespace drivenshape::cli
