// SPDX-License-Identifier: Apache-2.0
// The glue of the OpenCL LayerBackend (cl_layers.h): the program build, upload of the tables and
// the buffer helpers the launches share. The launches are one file per kernel stem: cl_mix.cpp
// (kernels/mix.cl) and cl_wind.cpp (kernels/wind.cl).

#include "cl_layers.h"

#include <memory>
#include <vector>

#include <drivenshape_kernels/layer_types_cl.h>
#include <drivenshape_kernels/mix_cl.h>
#include <drivenshape_kernels/wind_cl.h>
#include <shared_types.h>

#include "cl_backends.h"
#include "cl_program.h"
#include "layer_checks.h"

namespace drivenshape {

ClLayers::ClLayers(const cl_util::ClTarget& target)
    : mContext(target.context),
      mDevice(target.device),
      mQueue(target.queue),
      mTransfers(target.transfers) {
  mName =
      cl_util::guard("querying the device name", [&] { return mDevice.getInfo<CL_DEVICE_NAME>(); });
  mProgram =
      cl_util::buildProgram(target, {{kernels::kLayerTypesSourceName, kernels::kLayerTypesSource},
                                     {kernels::kMixSourceName, kernels::kMixSource},
                                     {kernels::kWindSourceName, kernels::kWindSource}});
  cl_util::guard("creating the layer kernels", [&] {
    mMix = cl::Kernel(mProgram, "dsMix");
    mWind = cl::Kernel(mProgram, "dsWind");
  });
}

void ClLayers::upload(const LayerTables& tables) {
  layer_checks::checkTables(tables);
  mUploaded = false;
  mVertexCount = tables.vertexCount;
  mHasMix = !tables.mixWeights.empty();
  mHasWind = !tables.windWeights.empty();
  cl_util::guard("uploading the layer tables", [&] {
    mRest = cl_util::readOnlyBuffer(mContext, tables.rest);
    // A one-float placeholder keeps every kernel argument a valid buffer.
    mMixWeights =
        cl_util::readOnlyBuffer(mContext, mHasMix ? tables.mixWeights : std::vector<float>{0.0f});
    mWindWeights =
        cl_util::readOnlyBuffer(mContext, mHasWind ? tables.windWeights : std::vector<float>{0.0f});
    mNoClearance = cl_util::readOnlyBuffer(mContext, std::vector<float>{0.0f});
  });
  mUploaded = true;
}

cl::Buffer& ClLayers::reserve(cl_util::GrowingBuffer& chunk, std::size_t bytes, const char* what) {
  return cl_util::guard(what, [&]() -> cl::Buffer& { return chunk.reserve(mContext, bytes); });
}

void ClLayers::enqueue(cl::Kernel& kernel, int frameCount) {
  mQueue.enqueueNDRangeKernel(
      kernel, cl::NullRange,
      cl::NDRange(cl_util::roundUp(static_cast<std::size_t>(mVertexCount), DS_LOCAL_SIZE),
                  static_cast<std::size_t>(frameCount)),
      cl::NDRange(DS_LOCAL_SIZE, 1));
}

std::unique_ptr<LayerBackend> makeClLayers(const cl_util::ClTarget& target) {
  return std::make_unique<ClLayers>(target);
}

std::unique_ptr<LayerBackend> makeClLayers(const cl::Context& context, const cl::Device& device,
                                           const cl::CommandQueue& queue) {
  return makeClLayers(cl_util::ClTarget{context, device, queue});
}

}  // namespace drivenshape
