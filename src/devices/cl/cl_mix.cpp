// SPDX-License-Identifier: Apache-2.0
// The launches of kernels/mix.cl: ClLayers::mix (cl_layers.h; the backend's glue is
// cl_layers.cpp).

#include "cl_layers.h"

#include <cstddef>

#include <layer_types.h>

#include "cl_program.h"
#include "layer_checks.h"

namespace drivenshape {

void ClLayers::mix(int frameCount, const float* other, float* positions) {
  layer_checks::checkCall("mix", mUploaded, mHasMix, frameCount);
  if (frameCount == 0) {
    return;
  }
  const std::size_t bytes = frameBytes(frameCount);
  cl::Buffer& positionBuffer = reserve(mPositions, bytes, "allocating the layer position buffer");
  cl::Buffer& otherBuffer = reserve(mOther, bytes, "allocating the mix cache buffer");
  cl_util::guard("uploading a chunk for the mix", [&] {
    cl_util::upload(mQueue, mTransfers, positionBuffer, CL_FALSE, 0, bytes, positions);
    cl_util::upload(mQueue, mTransfers, otherBuffer, CL_TRUE, 0, bytes, other);
  });
  DsMixParams params{};
  params.vertexCount = mVertexCount;
  params.frameCount = frameCount;
  cl_util::guard("running dsMix on a chunk of frames", [&] {
    cl_util::setArgs(mMix, positionBuffer, otherBuffer, mMixWeights, params);
    enqueue(mMix, frameCount);
  });
  cl_util::guard("reading back the mixed positions", [&] {
    cl_util::download(mQueue, mTransfers, positionBuffer, CL_TRUE, 0, bytes, positions);
  });
}

}  // namespace drivenshape
