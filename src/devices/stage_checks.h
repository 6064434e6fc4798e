// SPDX-License-Identifier: Apache-2.0
#pragma once
// Argument checks shared by the two StageBackend implementations, so the host reference and
// the OpenCL path refuse the same inputs with the same messages.

#include <cstddef>

#include <drivenshape/error.h>

#include "stages.h"

namespace drivenshape::stage_checks {

/// Throws Error(kInternal) unless the table sizes agree with the counts (see ShapeTables).
inline void checkTables(const ShapeTables& tables) {
  if (tables.shapeCount < 1 || tables.driverVertexCount < 1 || tables.drivenVertexCount < 1) {
    DS_THROW(kInternal, "stage tables need at least one shape and one vertex per mesh; got k = ",
             tables.shapeCount, ", driver vertices = ", tables.driverVertexCount,
             ", driven vertices = ", tables.drivenVertexCount);
  }
  const std::size_t k = static_cast<std::size_t>(tables.shapeCount);
  const std::size_t np = 3 * static_cast<std::size_t>(tables.driverVertexCount);
  const std::size_t nd = 3 * static_cast<std::size_t>(tables.drivenVertexCount);
  const auto expect = [](const char* what, std::size_t got, std::size_t want) {
    if (got != want) {
      DS_THROW(kInternal, "stage tables: ", what, " holds ", got, " floats, expected ", want);
    }
  };
  expect("drivenShapes (k x 3Vd)", tables.drivenShapes.size(), k * nd);
  if (tables.blendOnly()) {
    return;
  }
  expect("projectionRows ((k-1) x 3Vp)", tables.projectionRows.size(), (k - 1) * np);
  expect("center (3Vp)", tables.center.size(), np);
  expect("driverShapes (k x 3Vp)", tables.driverShapes.size(), k * np);
}

/// Throws Error(kInternal) for a call before upload() or with a negative frame count.
inline void checkCall(const char* call, bool uploaded, int frameCount) {
  if (!uploaded) {
    DS_THROW(kInternal, "StageBackend::", call, " called before upload()");
  }
  if (frameCount < 0) {
    DS_THROW(kInternal, "StageBackend::", call, " called with ", frameCount, " frames");
  }
}

/// Throws Error(kInternal) for a projection or a driver blend on blend-only tables.
inline void checkDriverTables(const char* call, const ShapeTables& tables) {
  if (tables.blendOnly()) {
    DS_THROW(kInternal, "StageBackend::", call,
             " needs the driver tables; these are blend-only (driven shapes alone)");
  }
}

}  // namespace drivenshape::stage_checks
