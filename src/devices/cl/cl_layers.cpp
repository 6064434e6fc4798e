// SPDX-License-Identifier: Apache-2.0
// The OpenCL implementation of LayerBackend (kernels/mix.cl, kernels/wind.cl). Tables go to the
// device once (upload); each mix()/wind() call uploads the chunk, runs one launch over all its
// frames and reads the chunk back. Chunk buffers are kept and only grow.

#include <drivenshape/error.h>
#include <drivenshape/layers.h>
#include "cl_backends.h"

#include <vector>

#include <drivenshape_kernels/layer_types_cl.h>
#include <drivenshape_kernels/mix_cl.h>
#include <drivenshape_kernels/wind_cl.h>
#include <layer_types.h>
#include <shared_types.h>

#include "cl_program.h"
#include "layer_checks.h"
#include "wind_params.h"

namespace drivenshape {
namespace {

using cl_util::guard;

class ClLayers final : public LayerBackend {
 public:
  ClLayers(const cl_util::ClTarget& target)
      : mContext(target.context),
        mDevice(target.device),
        mQueue(target.queue),
        mTransfers(target.transfers) {
    mName = guard("querying the device name", [&] { return mDevice.getInfo<CL_DEVICE_NAME>(); });
    mProgram =
        cl_util::buildProgram(target, {{kernels::kLayerTypesSourceName, kernels::kLayerTypesSource},
                                       {kernels::kMixSourceName, kernels::kMixSource},
                                       {kernels::kWindSourceName, kernels::kWindSource}});
    guard("creating the layer kernels", [&] {
      mMix = cl::Kernel(mProgram, "dsMix");
      mWind = cl::Kernel(mProgram, "dsWind");
    });
  }

  std::string name() const override { return mName; }

  void upload(const LayerTables& tables) override {
    layer_checks::checkTables(tables);
    mUploaded = false;
    mVertexCount = tables.vertexCount;
    mHasMix = !tables.mixWeights.empty();
    mHasWind = !tables.windWeights.empty();
    guard("uploading the layer tables", [&] {
      mRest = readOnlyBuffer(tables.rest);
      // A one-float placeholder keeps every kernel argument a valid buffer.
      mMixWeights = readOnlyBuffer(mHasMix ? tables.mixWeights : std::vector<float>{0.0f});
      mWindWeights = readOnlyBuffer(mHasWind ? tables.windWeights : std::vector<float>{0.0f});
      mNoClearance = readOnlyBuffer(std::vector<float>{0.0f});
    });
    mUploaded = true;
  }

  void mix(int frameCount, const float* other, float* positions) override {
    layer_checks::checkCall("mix", mUploaded, mHasMix, frameCount);
    if (frameCount == 0) {
      return;
    }
    const std::size_t bytes = frameBytes(frameCount);
    cl::Buffer& positionBuffer = reserve(mPositions, bytes, "allocating the layer position buffer");
    cl::Buffer& otherBuffer = reserve(mOther, bytes, "allocating the mix cache buffer");
    guard("uploading a chunk for the mix", [&] {
      cl_util::upload(mQueue, mTransfers, positionBuffer, CL_FALSE, 0, bytes, positions);
      cl_util::upload(mQueue, mTransfers, otherBuffer, CL_TRUE, 0, bytes, other);
    });
    DsMixParams params{};
    params.vertexCount = mVertexCount;
    params.frameCount = frameCount;
    guard("running dsMix on a chunk of frames", [&] {
      cl_util::setArgs(mMix, positionBuffer, otherBuffer, mMixWeights, params);
      enqueue(mMix, frameCount);
    });
    guard("reading back the mixed positions", [&] {
      cl_util::download(mQueue, mTransfers, positionBuffer, CL_TRUE, 0, bytes, positions);
    });
  }

  void wind(int frameCount, const int* frames, const WindSettings& settings, const float* clearance,
            float* positions) override {
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
    cl::Buffer& offsetBuffer = reserve(mOffsetBuffer, mOffsets.size() * sizeof(float),
                                       "allocating the wind offset buffer");
    const std::size_t clearanceBytes = count * static_cast<std::size_t>(mVertexCount) * 4;
    cl::Buffer& clearanceBuffer = clearance != nullptr ? reserve(mClearance, clearanceBytes,
                                                                 "allocating the clearance buffer")
                                                       : mNoClearance;
    guard("uploading a chunk for the wind", [&] {
      cl_util::upload(mQueue, mTransfers, positionBuffer, CL_FALSE, 0, bytes, positions);
      cl_util::upload(mQueue, mTransfers, offsetBuffer, CL_FALSE, 0,
                      mOffsets.size() * sizeof(float), mOffsets.data());
      if (clearance != nullptr) {
        cl_util::upload(mQueue, mTransfers, clearanceBuffer, CL_FALSE, 0, clearanceBytes,
                        clearance);
      }
      mQueue.finish();
    });
    const DsWindParams params =
        layer_detail::makeWindParams(settings, mVertexCount, frameCount, clearance != nullptr);
    guard("running dsWind on a chunk of frames", [&] {
      cl_util::setArgs(mWind, positionBuffer, mRest, mWindWeights, clearanceBuffer, offsetBuffer,
                       params);
      enqueue(mWind, frameCount);
    });
    guard("reading back the wind positions", [&] {
      cl_util::download(mQueue, mTransfers, positionBuffer, CL_TRUE, 0, bytes, positions);
    });
  }

 private:
  std::size_t frameBytes(int frameCount) const {
    return static_cast<std::size_t>(frameCount) * 3 * static_cast<std::size_t>(mVertexCount) *
           sizeof(float);
  }

  cl::Buffer readOnlyBuffer(const std::vector<float>& data) {
    return cl::Buffer(mContext, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                      data.size() * sizeof(float), const_cast<float*>(data.data()));
  }

  cl::Buffer& reserve(cl_util::GrowingBuffer& chunk, std::size_t bytes, const char* what) {
    return guard(what, [&]() -> cl::Buffer& { return chunk.reserve(mContext, bytes); });
  }

  // One item per (vertex, frame), rows of DS_LOCAL_SIZE vertices.
  void enqueue(cl::Kernel& kernel, int frameCount) {
    mQueue.enqueueNDRangeKernel(
        kernel, cl::NullRange,
        cl::NDRange(cl_util::roundUp(static_cast<std::size_t>(mVertexCount), DS_LOCAL_SIZE),
                    static_cast<std::size_t>(frameCount)),
        cl::NDRange(DS_LOCAL_SIZE, 1));
  }

  cl::Context mContext;
  cl::Device mDevice;
  cl::CommandQueue mQueue;
  cl_util::Transfers* mTransfers = nullptr;
  std::string mName;
  cl::Program mProgram;
  cl::Kernel mMix;
  cl::Kernel mWind;

  bool mUploaded = false;
  bool mHasMix = false;
  bool mHasWind = false;
  int mVertexCount = 0;
  cl::Buffer mRest;                                      // 3Vd
  cl::Buffer mMixWeights;                                // Vd (or 1 placeholder)
  cl::Buffer mWindWeights;                               // Vd (or 1 placeholder)
  cl::Buffer mNoClearance;                               // 1 placeholder
  cl_util::GrowingBuffer mPositions{CL_MEM_READ_WRITE};  // F x 3Vd
  cl_util::GrowingBuffer mOther{CL_MEM_READ_ONLY};       // F x 3Vd
  cl_util::GrowingBuffer mClearance{CL_MEM_READ_ONLY};   // F x Vd
  cl_util::GrowingBuffer mOffsetBuffer{CL_MEM_READ_ONLY};
  std::vector<float> mOffsets;
};

}  // namespace

std::unique_ptr<LayerBackend> makeClLayers(const cl_util::ClTarget& target) {
  return std::make_unique<ClLayers>(target);
}

std::unique_ptr<LayerBackend> makeClLayers(const cl::Context& context, const cl::Device& device,
                                           const cl::CommandQueue& queue) {
  return makeClLayers(cl_util::ClTarget{context, device, queue});
}

}  // namespace drivenshape
