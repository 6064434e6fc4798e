// SPDX-License-Identifier: Apache-2.0
#pragma once

// The rasterisation of a mesh's UV layout into a position map's tables, once per mesh and map
// size. The layout, the tables and the files: drivenshape/position_map.h.

#include <string>

#include <drivenshape/mesh.h>
#include <drivenshape/position_map.h>

namespace drivenshape {

/// Rasterises the UV layout of `mesh` into a width x height map with `padding` texels of
/// dilation. `meshName` (a path, usually) prefixes input errors. Throws Error(kUsage) for a
/// size outside 1..kMaxPositionMapSide or a padding outside 0..kMaxPositionMapPadding, and
/// Error(kInput) for a mesh without UVs, a face corner without a UV, or a UV outside [0, 1]
/// (naming the face, the UV index and its value).
PositionMapTables buildPositionMapTables(const Mesh& mesh, int width, int height, int padding,
                                         const std::string& meshName = "mesh");

}  // namespace drivenshape
