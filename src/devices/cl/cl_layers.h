// SPDX-License-Identifier: Apache-2.0
#pragma once

// The OpenCL implementation of LayerBackend (private to the devices room): the class ClLayers,
// whose members are defined one file per kernel stem. cl_layers.cpp holds the glue (program
// build, upload, buffer helpers), cl_mix.cpp the launches of kernels/mix.cl, cl_wind.cpp those
// of kernels/wind.cl. Tables go to the device once (upload); each mix()/wind() call uploads the
// chunk, runs one launch over all its frames and reads the chunk back. Chunk buffers are kept
// and only grow.

#include <cstddef>
#include <string>
#include <vector>

#include <CL/opencl.hpp>

#include <drivenshape/layer_backend.h>

#include "cl_program.h"

namespace drivenshape {

class ClLayers final : public LayerBackend {
 public:
  explicit ClLayers(const cl_util::ClTarget& target);

  std::string name() const override { return mName; }

  void upload(const LayerTables& tables) override;
  void mix(int frameCount, const float* other, float* positions) override;
  void wind(int frameCount, const int* frames, const WindSettings& settings, const float* clearance,
            float* positions) override;

 private:
  std::size_t frameBytes(int frameCount) const {
    return static_cast<std::size_t>(frameCount) * 3 * static_cast<std::size_t>(mVertexCount) *
           sizeof(float);
  }

  cl::Buffer& reserve(cl_util::GrowingBuffer& chunk, std::size_t bytes, const char* what);
  // One item per (vertex, frame), rows of DS_LOCAL_SIZE vertices.
  void enqueue(cl::Kernel& kernel, int frameCount);

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

}  // namespace drivenshape
