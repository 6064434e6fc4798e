// SPDX-License-Identifier: Apache-2.0
// The host reference of kernels/project.cl: HostStages::project (host_stages.h).

#include "host_stages.h"

#include <cstddef>
#include <vector>

#include <drivenshape/error.h>

#include "stage_checks.h"

namespace drivenshape {

void HostStages::project(int frameCount, const float* driverFrames, float* projections,
                         float* norms) {
  stage_checks::checkCall("project", mUploaded, frameCount);
  stage_checks::checkDriverTables("project", mTables);
  const std::size_t n = 3 * static_cast<std::size_t>(mTables.driverVertexCount);
  const std::size_t rows = static_cast<std::size_t>(mTables.shapeCount) - 1;
  if (frameCount > 0 &&
      (driverFrames == nullptr || norms == nullptr || (rows > 0 && projections == nullptr))) {
    DS_THROW(kInternal, "StageBackend::project called with a null buffer");
  }
  std::vector<double> d(n);
  for (std::size_t f = 0; f < static_cast<std::size_t>(frameCount); ++f) {
    const float* b = driverFrames + f * n;
    double rr = 0.0;
    double bb = 0.0;
    for (std::size_t j = 0; j < n; ++j) {
      d[j] = static_cast<double>(b[j]) - static_cast<double>(mTables.center[j]);
      rr += d[j] * d[j];
      bb += static_cast<double>(b[j]) * static_cast<double>(b[j]);
    }
    for (std::size_t r = 0; r < rows; ++r) {
      const float* row = mTables.projectionRows.data() + r * n;
      double p = 0.0;
      for (std::size_t j = 0; j < n; ++j) {
        p += static_cast<double>(row[j]) * d[j];
      }
      projections[f * rows + r] = static_cast<float>(p);
    }
    norms[2 * f] = static_cast<float>(rr);
    norms[2 * f + 1] = static_cast<float>(bb);
  }
}

}  // namespace drivenshape
