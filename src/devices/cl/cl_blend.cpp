// SPDX-License-Identifier: Apache-2.0
// The launches of kernels/blend.cl: ClStages::blend and blendBlock (cl_stages.h; the backend's
// glue is cl_stages.cpp).

#include "cl_stages.h"

#include <cstddef>

#include <drivenshape/error.h>
#include <shared_types.h>

#include "cl_program.h"
#include "stage_checks.h"

namespace drivenshape {

void ClStages::blend(int frameCount, const float* weights, float* driven, float* driver) {
  checkBlend(frameCount, weights, driven != nullptr, driver != nullptr);
  if (frameCount == 0) {
    return;
  }
  uploadWeights(frameCount, weights);
  const std::size_t frames = static_cast<std::size_t>(frameCount);
  blendInto(mDriven, frameCount, mDrivenOut, "blending the driven shapes");
  cl_util::guard("reading back blended shapes", [&] {
    readRows(mDrivenOut.buffer, driven, frames, mDriven.count, mDriven.padded);
  });
  if (driver != nullptr) {
    blendInto(mDriver, frameCount, mDriverOut, "blending the driver shapes");
    cl_util::guard("reading back blended shapes", [&] {
      readRows(mDriverOut.buffer, driver, frames, mDriver.count, mDriver.padded);
    });
  }
}

void ClStages::blendBlock(int frameCount, const float* weights, DeviceArray& driven,
                          DeviceArray* driver) {
  if (!cl_util::onContext(mContext, driven) ||
      (driver != nullptr && !cl_util::onContext(mContext, *driver))) {
    StageBackend::blendBlock(frameCount, weights, driven, driver);
    return;
  }
  checkBlend(frameCount, weights, true, driver != nullptr);
  if (frameCount == 0) {
    return;
  }
  uploadWeights(frameCount, weights);
  blendOnDevice(mDriven, frameCount, mDrivenOut, driven, "blending the driven shapes");
  if (driver != nullptr) {
    blendOnDevice(mDriver, frameCount, mDriverOut, *driver, "blending the driver shapes");
  }
}

void ClStages::checkBlend(int frameCount, const float* weights, bool drivenPresent,
                          bool driverWanted) const {
  stage_checks::checkCall("blend", mUploaded, frameCount);
  if (mBlendOnly && driverWanted) {
    DS_THROW(kInternal,
             "StageBackend::blend of the driver needs the driver tables; these are "
             "blend-only");
  }
  if (frameCount > 0 && (weights == nullptr || !drivenPresent)) {
    DS_THROW(kInternal, "StageBackend::blend called with a null buffer");
  }
}

/// Weights plus, per frame, sum(w) - 1 summed in double (the term that carries the reference
/// shape in blend.cl, where float rounding of the sum would cost whole ulps of positions far
/// from the origin), to the device.
void ClStages::uploadWeights(int frameCount, const float* weights) {
  const std::size_t frames = static_cast<std::size_t>(frameCount);
  const std::size_t k = static_cast<std::size_t>(mShapeCount);
  mStaging.resize(frames * (k + 1));
  for (std::size_t f = 0; f < frames; ++f) {
    double sum = 0.0;
    for (std::size_t i = 0; i < k; ++i) {
      mStaging[f * (k + 1) + i] = weights[f * k + i];
      sum += static_cast<double>(weights[f * k + i]);
    }
    mStaging[f * (k + 1) + k] = static_cast<float>(sum - 1.0);
  }
  reserve(mWeights, mStaging.size() * sizeof(float), CL_MEM_READ_ONLY, false,
          "allocating the weight buffer");
  cl_util::guard("uploading a chunk of blend weights", [&] {
    cl_util::upload(mQueue, mTransfers, mWeights.buffer, CL_TRUE, 0,
                    mStaging.size() * sizeof(float), mStaging.data());
  });
}

/// Blends `table` with the uploaded weights into `out` (padded rows) and copies the rows,
/// packed, into `result` on the device.
void ClStages::blendOnDevice(const BlendTable& table, int frameCount, ChunkBuffer& out,
                             DeviceArray& result, const char* what) {
  blendInto(table, frameCount, out, what);
  cl_util::guard("copying blended shapes on the device", [&] {
    copyRows(out.buffer, table.padded, cl_util::writeBuffer(result), table.count,
             static_cast<std::size_t>(frameCount), table.count);
  });
}

/// dsBlend of `table` with the uploaded weights into `out` (F x padded).
void ClStages::blendInto(const BlendTable& table, int frameCount, ChunkBuffer& out,
                         const char* what) {
  const std::size_t frames = static_cast<std::size_t>(frameCount);
  reserve(out, frames * table.padded * sizeof(float), CL_MEM_READ_WRITE, false,
          "allocating a blend output buffer");
  DsBlendParams params{};
  params.quadCount = static_cast<int>(table.padded / 4);
  params.shapeCount = mShapeCount;
  params.frameCount = frameCount;
  params.weightStride = mShapeCount + 1;
  cl_util::guard(what, [&] {
    mBlend.setArg(0, table.deltas);
    mBlend.setArg(1, table.reference);
    mBlend.setArg(2, mWeights.buffer);
    mBlend.setArg(3, out.buffer);
    mBlend.setArg(4, params);
    const std::size_t blocks = (frames + DS_BLEND_FRAMES - 1) / DS_BLEND_FRAMES;
    mQueue.enqueueNDRangeKernel(
        mBlend, cl::NullRange,
        cl::NDRange(cl_util::roundUp(static_cast<std::size_t>(params.quadCount), DS_LOCAL_SIZE),
                    blocks),
        cl::NDRange(DS_LOCAL_SIZE, 1));
  });
}

}  // namespace drivenshape
