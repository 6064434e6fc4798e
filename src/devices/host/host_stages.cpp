// SPDX-License-Identifier: Apache-2.0
// The host reference of the per-frame stages: plain loops, every sum in double, one rounding to
// float at the end. It is the oracle the OpenCL kernels are tested against, so it favours
// obviousness over speed.

#include <algorithm>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include "stages.h"

#include "stage_checks.h"

namespace drivenshape {
namespace {

class HostStages final : public StageBackend {
 public:
  std::string name() const override { return "host"; }

  void upload(const ShapeTables& tables) override {
    stage_checks::checkTables(tables);
    mTables = tables;
    mUploaded = true;
  }

  void project(int frameCount, const float* driverFrames, float* projections,
               float* norms) override {
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

  void blend(int frameCount, const float* weights, float* driven, float* driver) override {
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

 private:
  void blendShapes(int frameCount, const float* weights, const std::vector<float>& shapes,
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

  ShapeTables mTables;
  bool mUploaded = false;
  std::vector<double> mAccumulator;
};

}  // namespace

std::unique_ptr<StageBackend> makeHostStages() {
  return std::make_unique<HostStages>();
}

}  // namespace drivenshape
