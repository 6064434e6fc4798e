// SPDX-License-Identifier: Apache-2.0
// The OpenCL implementation of the position-map gather (kernels/posmap.cl). Tables go to the
// device once (upload); each evaluate() is one upload of the chunk's frames, one launch per
// kernel over all its frames, one read back. Output buffers are zero-filled once when they are
// allocated: the kernels write active texels only, so the rest stay 0 in every frame.

#include <drivenshape/position_map_backend.h>

#include <algorithm>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape_kernels/posmap_cl.h>
#include <shared_types.h>

#include "cl_program.h"
#include "posmap_checks.h"

namespace drivenshape {
namespace {

using cl_util::guard;

class ClPositionMaps final : public PositionMapBackend {
 public:
  ClPositionMaps(const cl_util::ClTarget& target)
      : mContext(target.context),
        mDevice(target.device),
        mQueue(target.queue),
        mTransfers(target.transfers) {
    guard("querying the device", [&] {
      mName = mDevice.getInfo<CL_DEVICE_NAME>();
      mMaxAlloc = static_cast<std::size_t>(mDevice.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>());
    });
    mProgram =
        cl_util::buildProgram(target, {{kernels::kPosmapSourceName, kernels::kPosmapSource}});
    guard("creating the position-map kernels", [&] {
      mNormalsKernel = cl::Kernel(mProgram, "dsPosmapVertexNormals");
      mGatherKernel = cl::Kernel(mProgram, "dsPosmapGather");
    });
  }

  std::string name() const override { return mName; }

  void upload(const PositionMapTables& tables) override {
    posmap_checks::checkTables(tables);
    mUploaded = false;
    // A new layout has other active texels: old outputs would keep stale values where the new
    // layout has none, so they are reallocated (and zeroed) on the next call.
    mFrames = ChunkBuffer{};
    mVertexNormals = ChunkBuffer{};
    mPositions = ChunkBuffer{};
    mNormals = ChunkBuffer{};
    mVertexCount = tables.vertexCount;
    mActiveCount = tables.activeCount();
    mTexelCount = tables.texelCount();
    guard("uploading the position-map tables", [&] {
      mTriangles = cl_util::readOnlyBuffer(mContext, tables.triangles);
      mTriStart = cl_util::readOnlyBuffer(mContext, tables.vertexTriangleStart);
      mTriIds = cl_util::readOnlyBuffer(mContext, tables.vertexTriangles);
      mTexels = cl_util::readOnlyBuffer(mContext, tables.texels);
      mTexelTriangles = cl_util::readOnlyBuffer(mContext, tables.texelTriangles);
      mTexelWeights = cl_util::readOnlyBuffer(mContext, tables.texelWeights);
    });
    mUploaded = true;
  }

  void evaluate(int frameCount, const float* frames, float* positions, float* normals) override {
    posmap_checks::checkCall(mUploaded, frameCount, frames, positions);
    if (frameCount == 0) {
      return;
    }
    const std::size_t count = static_cast<std::size_t>(frameCount);
    const std::size_t vertexFloats = 3 * static_cast<std::size_t>(mVertexCount);
    const std::size_t mapFloats = 3 * mTexelCount;
    const bool withNormals = normals != nullptr;

    reserve(mFrames, count * vertexFloats * sizeof(float), CL_MEM_READ_ONLY, false,
            "allocating the frame buffer");
    reserve(mPositions, count * mapFloats * sizeof(float), CL_MEM_WRITE_ONLY, true,
            "allocating the position-map buffer");
    if (withNormals) {
      reserve(mVertexNormals, count * vertexFloats * sizeof(float), CL_MEM_READ_WRITE, false,
              "allocating the vertex-normal buffer");
      reserve(mNormals, count * mapFloats * sizeof(float), CL_MEM_WRITE_ONLY, true,
              "allocating the normal-map buffer");
    }
    guard("uploading a chunk of frames", [&] {
      cl_util::upload(mQueue, mTransfers, mFrames.buffer, CL_TRUE, 0,
                      count * vertexFloats * sizeof(float), frames);
    });
    if (withNormals) {
      guard("running dsPosmapVertexNormals on a chunk of frames", [&] {
        mNormalsKernel.setArg(0, mFrames.buffer);
        mNormalsKernel.setArg(1, mTriangles);
        mNormalsKernel.setArg(2, mTriStart);
        mNormalsKernel.setArg(3, mTriIds);
        mNormalsKernel.setArg(4, mVertexNormals.buffer);
        mNormalsKernel.setArg(5, mVertexCount);
        mNormalsKernel.setArg(6, frameCount);
        mQueue.enqueueNDRangeKernel(
            mNormalsKernel, cl::NullRange,
            cl::NDRange(cl_util::roundUp(static_cast<std::size_t>(mVertexCount), DS_LOCAL_SIZE),
                        count),
            cl::NDRange(DS_LOCAL_SIZE, 1));
      });
    }
    if (mActiveCount > 0) {
      guard("running dsPosmapGather on a chunk of frames", [&] {
        mGatherKernel.setArg(0, mFrames.buffer);
        mGatherKernel.setArg(1, withNormals ? mVertexNormals.buffer : mFrames.buffer);
        mGatherKernel.setArg(2, mTriangles);
        mGatherKernel.setArg(3, mTexels);
        mGatherKernel.setArg(4, mTexelTriangles);
        mGatherKernel.setArg(5, mTexelWeights);
        mGatherKernel.setArg(6, mPositions.buffer);
        mGatherKernel.setArg(7, withNormals ? mNormals.buffer : mPositions.buffer);
        mGatherKernel.setArg(8, static_cast<int>(mActiveCount));
        mGatherKernel.setArg(9, mVertexCount);
        mGatherKernel.setArg(10, static_cast<int>(mTexelCount));
        mGatherKernel.setArg(11, frameCount);
        mGatherKernel.setArg(12, withNormals ? 1 : 0);
        mQueue.enqueueNDRangeKernel(mGatherKernel, cl::NullRange,
                                    cl::NDRange(cl_util::roundUp(mActiveCount, DS_LOCAL_SIZE)),
                                    cl::NDRange(DS_LOCAL_SIZE));
      });
    }
    // Blocking reads: the caller's memory may go away as soon as we return or throw.
    guard("reading back the position maps", [&] {
      cl_util::download(mQueue, mTransfers, mPositions.buffer, CL_TRUE, 0,
                        count * mapFloats * sizeof(float), positions);
      if (withNormals) {
        cl_util::download(mQueue, mTransfers, mNormals.buffer, CL_TRUE, 0,
                          count * mapFloats * sizeof(float), normals);
      }
    });
  }

  std::size_t maxBufferBytes() const override { return mMaxAlloc; }

 private:
  // A chunk-sized device buffer, reallocated only when a bigger chunk comes.
  struct ChunkBuffer {
    cl::Buffer buffer;
    std::size_t bytes = 0;
  };

  void reserve(ChunkBuffer& chunk, std::size_t bytes, cl_mem_flags flags, bool zeroFill,
               const char* what) {
    if (chunk.bytes >= bytes) {
      return;
    }
    if (bytes > mMaxAlloc) {
      DS_THROW(kDevice, "OpenCL device '", mName, "' cannot hold ", bytes >> 20, " MiB in one ",
               "buffer (its limit is ", mMaxAlloc >> 20, " MiB) while ", what,
               "; write fewer frames per launch or a smaller --res");
    }
    guard(what, [&] {
      chunk.buffer = cl::Buffer(mContext, flags, bytes);
      if (zeroFill) {
        mQueue.enqueueFillBuffer(chunk.buffer, 0.0f, 0, bytes);
      }
    });
    chunk.bytes = bytes;
  }

  cl::Context mContext;
  cl::Device mDevice;
  cl::CommandQueue mQueue;
  cl_util::Transfers* mTransfers = nullptr;
  std::string mName;
  std::size_t mMaxAlloc = 0;
  cl::Program mProgram;
  cl::Kernel mNormalsKernel;
  cl::Kernel mGatherKernel;

  bool mUploaded = false;
  int mVertexCount = 0;
  std::size_t mActiveCount = 0;
  std::size_t mTexelCount = 0;
  cl::Buffer mTriangles;       // T x 3
  cl::Buffer mTriStart;        // V + 1
  cl::Buffer mTriIds;          // 3T
  cl::Buffer mTexels;          // E
  cl::Buffer mTexelTriangles;  // E
  cl::Buffer mTexelWeights;    // E x 2

  ChunkBuffer mFrames;         // F x 3V
  ChunkBuffer mVertexNormals;  // F x 3V
  ChunkBuffer mPositions;      // F x 3M, zeroed once
  ChunkBuffer mNormals;        // F x 3M, zeroed once
};

}  // namespace

std::unique_ptr<PositionMapBackend> makeClPositionMaps(const cl_util::ClTarget& target) {
  return std::make_unique<ClPositionMaps>(target);
}

std::unique_ptr<PositionMapBackend> makeClPositionMaps(const cl::Context& context,
                                                       const cl::Device& device,
                                                       const cl::CommandQueue& queue) {
  return makeClPositionMaps(cl_util::ClTarget{context, device, queue});
}

}  // namespace drivenshape
