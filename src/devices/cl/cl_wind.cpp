// SPDX-License-Identifier: Apache-2.0
// The launches of kernels/wind.cl: ClLayers::wind (cl_layers.h; the backend's glue is
// cl_layers.cpp).

#include "cl_layers.h"

#include <cstddef>

#include <layer_types.h>

#include "cl_program.h"
#include "layer_checks.h"
#include "wind_params.h"

namespace drivenshape {

void ClLayers::wind(int frameCount, const int* frames, const WindSettings& settings,
                    const float* clearance, float* positions) {
  layer_checks::checkCall("wind", mUploaded, mHasWind, frameCount);
  layer_checks::checkWind(settings);
  if (frameCount == 0) {
    return;
  }
  const std::size_t count = static_cast<std::size_t>(frameCount);
  const std::size_t bytes = frameBytes(frameCount);
  mOffsets.resize(count * DS_WIND_MAX_OCTAVES * 4);
  for (std::size_t f = 0; f < count; ++f) {
    windFrameOffsets(settings, frames[f], mOffsets.data() + f * DS_WIND_MAX_OCTAVES * 4);
  }
  cl::Buffer& positionBuffer = reserve(mPositions, bytes, "allocating the layer position buffer");
  cl::Buffer& offsetBuffer =
      reserve(mOffsetBuffer, mOffsets.size() * sizeof(float), "allocating the wind offset buffer");
  const std::size_t clearanceBytes = count * static_cast<std::size_t>(mVertexCount) * 4;
  cl::Buffer& clearanceBuffer =
      clearance != nullptr ? reserve(mClearance, clearanceBytes, "allocating the clearance buffer")
                           : mNoClearance;
  cl_util::guard("uploading a chunk for the wind", [&] {
    cl_util::upload(mQueue, mTransfers, positionBuffer, CL_FALSE, 0, bytes, positions);
    cl_util::upload(mQueue, mTransfers, offsetBuffer, CL_FALSE, 0, mOffsets.size() * sizeof(float),
                    mOffsets.data());
    if (clearance != nullptr) {
      cl_util::upload(mQueue, mTransfers, clearanceBuffer, CL_FALSE, 0, clearanceBytes, clearance);
    }
    mQueue.finish();
  });
  const DsWindParams params =
      layer_detail::makeWindParams(settings, mVertexCount, frameCount, clearance != nullptr);
  cl_util::guard("running dsWind on a chunk of frames", [&] {
    cl_util::setArgs(mWind, positionBuffer, mRest, mWindWeights, clearanceBuffer, offsetBuffer,
                     params);
    enqueue(mWind, frameCount);
  });
  cl_util::guard("reading back the wind positions", [&] {
    cl_util::download(mQueue, mTransfers, positionBuffer, CL_TRUE, 0, bytes, positions);
  });
}

}  // namespace drivenshape
