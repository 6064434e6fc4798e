// SPDX-License-Identifier: Apache-2.0
#pragma once

// The OpenCL implementation of the per-frame stages (private to the devices room): the class
// ClStages, whose members are defined one file per kernel stem. cl_stages.cpp holds the glue
// (program build, upload, buffer helpers), cl_project.cpp the launches of kernels/project.cl,
// cl_blend.cpp those of kernels/blend.cl. Tables go to the device once (upload); each
// project()/blend() call is one upload of the chunk, one launch per output over all its frames,
// one read back. Chunk buffers are kept and only grow.

#include <cstddef>
#include <string>
#include <vector>

#include <CL/opencl.hpp>

#include "stages.h"

#include "cl_program.h"

namespace drivenshape {
namespace cl_stages {

// Device rows are padded from n = 3V floats to a multiple of 4, so each row starts on a float4
// and the kernels never need a scalar tail. Padding is zero and never written:
//
//   host row   | x0 y0 z0 x1 | y1 z1 x2 y2 | z2 |           n = 9, rows packed
//   device row | x0 y0 z0 x1 | y1 z1 x2 y2 | z2 0  0  0 |   padded = 12
//
// Chunks move between the two layouts with rectangular copies (row pitch 4n vs 4 padded).
inline std::size_t paddedCount(std::size_t count) {
  return cl_util::roundUp(count, 4);
}

}  // namespace cl_stages

class ClStages final : public StageBackend {
 public:
  explicit ClStages(const cl_util::ClTarget& target);

  std::string name() const override { return mName; }

  void upload(const ShapeTables& tables) override;
  void project(int frameCount, const float* driverFrames, float* projections,
               float* norms) override;
  void projectBlock(int frameCount, DeviceArray& driverFrames, float* projections,
                    float* norms) override;
  void blend(int frameCount, const float* weights, float* driven, float* driver) override;
  void blendBlock(int frameCount, const float* weights, DeviceArray& driven,
                  DeviceArray* driver) override;

 private:
  // A chunk-sized device buffer, reallocated only when a bigger chunk comes.
  struct ChunkBuffer {
    cl::Buffer buffer;
    std::size_t bytes = 0;
  };

  // One blendable mesh on the device: its shapes centred on `reference` (see blend.cl).
  struct BlendTable {
    cl::Buffer deltas;     // k x padded
    cl::Buffer reference;  // padded
    std::size_t count = 0;
    std::size_t padded = 0;
  };

  // Glue (cl_stages.cpp).
  BlendTable makeBlendTable(const std::vector<float>& shapes, std::size_t count);
  void reserve(ChunkBuffer& chunk, std::size_t bytes, cl_mem_flags flags, bool zeroFill,
               const char* what);
  void writeRows(const cl::Buffer& buffer, const float* data, std::size_t rows, std::size_t count,
                 std::size_t padded);
  void readRows(const cl::Buffer& buffer, float* data, std::size_t rows, std::size_t count,
                std::size_t padded);
  void copyRows(const cl::Buffer& from, std::size_t fromPitch, const cl::Buffer& to,
                std::size_t toPitch, std::size_t rows, std::size_t count);

  // kernels/project.cl (cl_project.cpp).
  void checkProject(int frameCount, bool framesPresent, const float* projections,
                    const float* norms) const;
  void reserveFrames(std::size_t frames);
  void projectFrames(int frameCount, float* projections, float* norms);

  // kernels/blend.cl (cl_blend.cpp).
  void checkBlend(int frameCount, const float* weights, bool drivenPresent,
                  bool driverWanted) const;
  void uploadWeights(int frameCount, const float* weights);
  void blendOnDevice(const BlendTable& table, int frameCount, ChunkBuffer& out, DeviceArray& result,
                     const char* what);
  void blendInto(const BlendTable& table, int frameCount, ChunkBuffer& out, const char* what);

  cl::Context mContext;
  cl::Device mDevice;
  cl::CommandQueue mQueue;
  cl_util::Transfers* mTransfers = nullptr;
  std::string mName;
  cl::Program mProgram;
  cl::Kernel mProject;
  cl::Kernel mBlend;

  bool mUploaded = false;
  int mShapeCount = 0;
  int mRowCount = 0;
  bool mBlendOnly = false;
  int mTileCount = 0;
  std::size_t mDriverCount = 0;
  std::size_t mDriverPadded = 0;
  cl::Buffer mRows;    // tileCount * DS_PROJECT_ROWS x padded, zero rows past k-1
  cl::Buffer mCenter;  // padded
  BlendTable mDriven;
  BlendTable mDriver;

  ChunkBuffer mFrames;     // F x padded driver frames (padding zeroed once)
  ChunkBuffer mProjected;  // F x (k+1): k-1 projections, ||b-m||^2, ||b||^2
  ChunkBuffer mWeights;    // F x (k+1): weights, sum(w) - 1
  ChunkBuffer mDrivenOut;  // F x padded driven
  ChunkBuffer mDriverOut;  // F x padded driver
  std::vector<float> mStaging;
};

}  // namespace drivenshape
