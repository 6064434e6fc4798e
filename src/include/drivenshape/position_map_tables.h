// SPDX-License-Identifier: Apache-2.0
#pragma once

// The rasterisation of a mesh's UV layout into a position map's tables, once per mesh and map
// size. The layout, the tables and the files: drivenshape/position_map.h.

#include <memory>
#include <string>

#include <drivenshape/mesh.h>
#include <drivenshape/position_map.h>

namespace drivenshape {

/// The UV layout of a mesh prepared once for a width x height map with `padding` texels of
/// dilation, rasterised a band of rows at a time: a map too large to hold its tables whole
/// (16384^2 texels need 5 GiB of them) is written band by band (PositionMapWriter).
///
///     PositionMapRaster raster(mesh, 16384, 16384, 8, "cloth.obj");
///     const PositionMapTables rows = raster.band(0, 256);  // rows 0-255 as a 16384 x 256 map
class PositionMapRaster {
 public:
  /// Checks as buildPositionMapTables does (Error(kUsage) for the size and padding,
  /// Error(kInput) for the mesh and its UVs).
  PositionMapRaster(const Mesh& mesh, int width, int height, int padding,
                    const std::string& meshName = "mesh");
  ~PositionMapRaster();
  PositionMapRaster(const PositionMapRaster&) = delete;
  PositionMapRaster& operator=(const PositionMapRaster&) = delete;

  /// The map's sizes and triangle tables, without texels (no counts, no overlaps).
  const PositionMapTables& shared() const;
  /// The tables of rows [firstRow, firstRow + rows): those of a width x rows map whose row y is
  /// row firstRow + y of the whole map, every texel with the triangle, weights and coverage
  /// that buildPositionMapTables gives it (the padding reaches across the band's edges: it is
  /// decided by the whole map's islands). coveredCount, paddedCount and overlaps count the
  /// band's rows; texelSources of a padded texel whose source lies in another band is -1.
  PositionMapTables band(int firstRow, int rows) const;
  /// The whole map's counts (coveredCount, paddedCount, overlaps: each overlapping face pair
  /// once, the examples in the order the bands find them) with the shared tables and no texel,
  /// rasterised `bandRows` rows at a time.
  PositionMapTables survey(int bandRows) const;

 private:
  struct Layout;
  std::unique_ptr<Layout> mLayout;
};

/// Rasterises the UV layout of `mesh` into a width x height map with `padding` texels of
/// dilation. `meshName` (a path, usually) prefixes input errors. Throws Error(kUsage) for a
/// size outside 1..kMaxPositionMapSide or a padding outside 0..kMaxPositionMapPadding, and
/// Error(kInput) for a mesh without UVs, a face corner without a UV, or a UV outside [0, 1]
/// (naming the face, the UV index and its value). PositionMapRaster(...).band(0, height).
PositionMapTables buildPositionMapTables(const Mesh& mesh, int width, int height, int padding,
                                         const std::string& meshName = "mesh");

}  // namespace drivenshape
