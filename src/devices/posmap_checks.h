// SPDX-License-Identifier: Apache-2.0
#pragma once
// Checks shared by the two PositionMapBackend implementations, so the host reference and the
// OpenCL path refuse the same inputs with the same messages.

#include <cstddef>

#include <drivenshape/error.h>
#include <drivenshape/position_map_backend.h>

namespace drivenshape::posmap_checks {

/// Throws Error(kInternal) unless the table sizes agree with each other (see
/// PositionMapTables).
inline void checkTables(const PositionMapTables& tables) {
  if (tables.width < 1 || tables.height < 1 || tables.vertexCount < 1) {
    DS_THROW(kInternal, "position map tables need a size and vertices; got ", tables.width, "x",
             tables.height, " and ", tables.vertexCount, " vertices");
  }
  const std::size_t active = tables.texels.size();
  const std::size_t triangles = tables.triangles.size() / 3;
  const auto expect = [](const char* what, std::size_t got, std::size_t want) {
    if (got != want) {
      DS_THROW(kInternal, "position map tables: ", what, " holds ", got, " values, expected ",
               want);
    }
  };
  expect("triangles (T x 3)", tables.triangles.size(), 3 * triangles);
  expect("vertexTriangleStart (V + 1)", tables.vertexTriangleStart.size(),
         static_cast<std::size_t>(tables.vertexCount) + 1);
  expect("vertexTriangles (3T)", tables.vertexTriangles.size(), 3 * triangles);
  expect("texelTriangles (E)", tables.texelTriangles.size(), active);
  expect("texelWeights (E x 2)", tables.texelWeights.size(), 2 * active);
  expect("coverage (W x H)", tables.coverage.size(), tables.texelCount());
}

/// Throws Error(kInternal) for a call before upload(), a negative frame count or null blocks.
inline void checkCall(bool uploaded, int frameCount, const float* frames, const float* positions) {
  if (!uploaded) {
    DS_THROW(kInternal, "PositionMapBackend::evaluate called before upload()");
  }
  if (frameCount < 0) {
    DS_THROW(kInternal, "PositionMapBackend::evaluate called with ", frameCount, " frames");
  }
  if (frameCount > 0 && (frames == nullptr || positions == nullptr)) {
    DS_THROW(kInternal, "PositionMapBackend::evaluate called with a null buffer");
  }
}

}  // namespace drivenshape::posmap_checks
