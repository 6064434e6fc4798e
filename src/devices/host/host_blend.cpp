// SPDX-License-Identifier: Apache-2.0
// The host reference of kernels/blend.cl: HostStages::blend (host_stages.h).

#include "host_stages.h"

#include <algorithm>
#include <cstddef>
#include <vector>

#include <drivenshape/error.h>

#include "stage_checks.h"

namespace drivenshape {

void HostStages::blend(int frameCount, const float* weights, float* driven, float* driver) {
  stage_checks::checkCall("blend", mUploaded, frameCount);
  if (frameCount > 0 && (weights == nullptr || driven == nullptr)) {
    DS_THROW(kInternal, "StageBackend::blend called with a null buffer");
  }
  blendShapes(frameCount, weights, mTables.drivenShapes, mTables.drivenVertexCount, driven);
  if (driver != nullptr) {
    stage_checks::checkDriverTables("blend", mTables);
    blendShapes(frameCount, weights, mTables.driverShapes, mTables.driverVertexCount, driver);
  }
}

void HostStages::blendShapes(int frameCount, const float* weights, const std::vector<float>& shapes,
                             int vertexCount, float* out) {
  const std::size_t n = 3 * static_cast<std::size_t>(vertexCount);
  const std::size_t k = static_cast<std::size_t>(mTables.shapeCount);
  mAccumulator.assign(n, 0.0);
  for (std::size_t f = 0; f < static_cast<std::size_t>(frameCount); ++f) {
    std::fill(mAccumulator.begin(), mAccumulator.end(), 0.0);
    for (std::size_t i = 0; i < k; ++i) {
      const double w = static_cast<double>(weights[f * k + i]);
      const float* shape = shapes.data() + i * n;
      for (std::size_t j = 0; j < n; ++j) {
        mAccumulator[j] += w * static_cast<double>(shape[j]);
      }
    }
    float* frameOut = out + f * n;
    for (std::size_t j = 0; j < n; ++j) {
      frameOut[j] = static_cast<float>(mAccumulator[j]);
    }
  }
}

}  // namespace drivenshape
