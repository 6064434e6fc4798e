// SPDX-License-Identifier: Apache-2.0
// The OpenCL StrainLimitBackend (strain_limit.h): the tables go to the device once (upload); a
// call runs kernels/strain_limit.cl once per iteration over every vertex of every frame of the
// block, ping-ponging between the positions and a scratch buffer of the same size, and copies the
// last iteration back into the positions when it landed in the scratch. On a DeviceArray of this
// context nothing goes through the host.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <CL/opencl.hpp>

#include <drivenshape_kernels/strain_limit_cl.h>
#include <shared_types.h>

#include "cl_backends.h"
#include "cl_program.h"
#include "strain_limit.h"

namespace drivenshape {
namespace {

class ClStrainLimit final : public StrainLimitBackend {
 public:
  explicit ClStrainLimit(const cl_util::ClTarget& target)
      : mContext(target.context),
        mDevice(target.device),
        mQueue(target.queue),
        mTransfers(target.transfers) {
    mName = cl_util::guard("querying the device name",
                           [&] { return mDevice.getInfo<CL_DEVICE_NAME>(); });
    mProgram = cl_util::buildProgram(
        target, {{kernels::kStrainLimitSourceName, kernels::kStrainLimitSource}});
    cl_util::guard("creating the strain-limit kernels", [&] {
      mKernel = cl::Kernel(mProgram, "dsStrainLimit");
      mStayedKernel = cl::Kernel(mProgram, "dsStrainStayed");
      mInFrontKernel = cl::Kernel(mProgram, "dsStrainInFront");
    });
  }

  std::string name() const override { return mName; }

  void upload(const StrainLimitTables& tables) override {
    strain_limit_checks::checkTables(tables);
    mUploaded = false;
    mVertexCount = tables.vertexCount;
    mIterations = tables.iterations;
    mOmega = tables.omega;
    mCompression = tables.compression;
    cl_util::guard("uploading the strain-limit tables", [&] {
      mStart = cl_util::readOnlyBuffer(mContext, tables.start);
      mOther = cl_util::readOnlyBuffer(mContext, tables.other);
      mLower = cl_util::readOnlyBuffer(mContext, tables.lower);
      mUpper = cl_util::readOnlyBuffer(mContext, tables.upper);
      mShare = cl_util::readOnlyBuffer(mContext, tables.share);
      mStep = cl_util::readOnlyBuffer(mContext, tables.step);
    });
    mUploaded = true;
  }

  void limit(int frameCount, float* positions, const float* planes, std::int32_t* stayed,
             float reach) override {
    strain_limit_checks::checkCall(mUploaded, frameCount);
    if (frameCount == 0 || mIterations == 0) {
      return;
    }
    const std::size_t bytes = frameBytes(frameCount);
    cl::Buffer& buffer =
        cl_util::guard("allocating the strain-limit position buffer",
                       [&]() -> cl::Buffer& { return mPositions.reserve(mContext, bytes); });
    const cl::Buffer* planeBuffer = nullptr;
    cl_util::guard("uploading a chunk for the strain limit", [&] {
      cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, bytes, positions);
      if (planes != nullptr) {
        const std::size_t planeBytes = bytes / 3 * 4;
        cl::Buffer& planeTarget = mPlanes.reserve(mContext, planeBytes);
        cl_util::upload(mQueue, mTransfers, planeTarget, CL_TRUE, 0, planeBytes, planes);
        planeBuffer = &planeTarget;
      }
    });
    const std::size_t markBytes = bytes / 3 / sizeof(float) * sizeof(std::int32_t);
    cl::Buffer* markBuffer = nullptr;
    if (stayed != nullptr) {
      cl_util::guard("uploading the strain limit's marks", [&] {
        markBuffer = &mMarks.reserve(mContext, markBytes);
        cl_util::upload(mQueue, mTransfers, *markBuffer, CL_TRUE, 0, markBytes, stayed);
      });
    }
    iterate(frameCount, buffer, planeBuffer, markBuffer, reach);
    cl_util::guard("reading back the strain-limited positions", [&] {
      cl_util::download(mQueue, mTransfers, buffer, CL_TRUE, 0, bytes, positions);
      if (stayed != nullptr) {
        cl_util::download(mQueue, mTransfers, *markBuffer, CL_TRUE, 0, markBytes, stayed);
      }
    });
  }

  void limitBlock(int frameCount, DeviceArray& positions, DeviceArray* planes, DeviceArray* stayed,
                  float reach) override {
    if (!cl_util::onContext(mContext, positions) ||
        (planes != nullptr && !cl_util::onContext(mContext, *planes)) ||
        (stayed != nullptr && !cl_util::onContext(mContext, *stayed))) {
      StrainLimitBackend::limitBlock(frameCount, positions, planes, stayed, reach);
      return;
    }
    strain_limit_checks::checkCall(mUploaded, frameCount);
    if (frameCount == 0 || mIterations == 0) {
      return;
    }
    iterate(frameCount, cl_util::modifyBuffer(positions),
            planes != nullptr ? &cl_util::readBuffer(*planes) : nullptr,
            stayed != nullptr ? &cl_util::modifyBuffer(*stayed) : nullptr, reach);
  }

  void keepInFront(int frameCount, int vertexCount, float* positions,
                   const float* planes) override {
    strain_limit_checks::checkInFront(frameCount, vertexCount);
    const std::size_t items = static_cast<std::size_t>(frameCount) * vertexCount;
    if (items == 0) {
      return;
    }
    cl_util::guard("keeping a chunk in front of its planes", [&] {
      cl::Buffer& buffer = mPositions.reserve(mContext, items * 3 * sizeof(float));
      cl::Buffer& planeBuffer = mPlanes.reserve(mContext, items * 4 * sizeof(float));
      cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, items * 3 * sizeof(float), positions);
      cl_util::upload(mQueue, mTransfers, planeBuffer, CL_TRUE, 0, items * 4 * sizeof(float),
                      planes);
      inFront(frameCount, vertexCount, buffer, planeBuffer);
      cl_util::download(mQueue, mTransfers, buffer, CL_TRUE, 0, items * 3 * sizeof(float),
                        positions);
    });
  }

  void keepInFrontBlock(int frameCount, int vertexCount, DeviceArray& positions,
                        DeviceArray& planes) override {
    if (!cl_util::onContext(mContext, positions) || !cl_util::onContext(mContext, planes)) {
      StrainLimitBackend::keepInFrontBlock(frameCount, vertexCount, positions, planes);
      return;
    }
    strain_limit_checks::checkInFront(frameCount, vertexCount);
    if (static_cast<std::size_t>(frameCount) * vertexCount == 0) {
      return;
    }
    cl_util::guard("keeping a chunk in front of its planes", [&] {
      inFront(frameCount, vertexCount, cl_util::modifyBuffer(positions),
              cl_util::readBuffer(planes));
    });
  }

 private:
  /// dsStrainInFront on `frameCount` frames of `vertexCount` vertices on the device.
  void inFront(int frameCount, int vertexCount, cl::Buffer& positions, const cl::Buffer& planes) {
    DsStrainLimitParams params{};
    params.vertexCount = vertexCount;
    params.frameCount = frameCount;
    cl_util::setArgs(mInFrontKernel, positions, planes, params);
    mQueue.enqueueNDRangeKernel(
        mInFrontKernel, cl::NullRange,
        cl::NDRange(cl_util::roundUp(static_cast<std::size_t>(vertexCount), DS_LOCAL_SIZE),
                    static_cast<std::size_t>(frameCount)),
        cl::NDRange(DS_LOCAL_SIZE, 1));
  }

  std::size_t frameBytes(int frameCount) const {
    return static_cast<std::size_t>(frameCount) * 3 * static_cast<std::size_t>(mVertexCount) *
           sizeof(float);
  }

  /// The iterations on `positions` (F x 3V floats on the device), in place, with `planes` (F x 4V
  /// floats on the device, or null) and the marks `stayed` (F x V ints, or null) updated after.
  void iterate(int frameCount, cl::Buffer& positions, const cl::Buffer* planes, cl::Buffer* stayed,
               float reach) {
    const std::size_t bytes = frameBytes(frameCount);
    cl_util::guard("running dsStrainLimit on a chunk of frames", [&] {
      cl::Buffer& scratch = mScratch.reserve(mContext, bytes);
      DsStrainLimitParams params{};
      params.vertexCount = mVertexCount;
      params.frameCount = frameCount;
      params.planes = planes != nullptr ? 1 : 0;
      params.compression = mCompression;
      // Without planes any buffer stands in for them: the kernel does not read it.
      const cl::Buffer& planeArg = planes != nullptr ? *planes : mStep;
      const cl::NDRange global(
          cl_util::roundUp(static_cast<std::size_t>(mVertexCount), DS_LOCAL_SIZE),
          static_cast<std::size_t>(frameCount));
      // The marks need where every vertex started: a copy, taken only when asked for.
      cl::Buffer& start = stayed != nullptr ? mStartPositions.reserve(mContext, bytes) : scratch;
      if (stayed != nullptr) {
        mQueue.enqueueCopyBuffer(positions, start, 0, 0, bytes);
      }
      const cl::Buffer* from = &positions;
      const cl::Buffer* to = &scratch;
      for (int i = 0; i < mIterations; ++i) {
        params.omega = mOmega[static_cast<std::size_t>(i)];
        cl_util::setArgs(mKernel, *from, *to, mStart, mOther, mLower, mUpper, mShare, mStep,
                         planeArg, params);
        mQueue.enqueueNDRangeKernel(mKernel, cl::NullRange, global, cl::NDRange(DS_LOCAL_SIZE, 1));
        std::swap(from, to);
      }
      if (from != &positions) {
        mQueue.enqueueCopyBuffer(*from, positions, 0, 0, bytes);
      }
      if (stayed != nullptr) {
        params.reach = reach;
        cl_util::setArgs(mStayedKernel, start, positions, *stayed, params);
        mQueue.enqueueNDRangeKernel(mStayedKernel, cl::NullRange, global,
                                    cl::NDRange(DS_LOCAL_SIZE, 1));
      }
    });
  }

  cl::Context mContext;
  cl::Device mDevice;
  cl::CommandQueue mQueue;
  cl_util::Transfers* mTransfers = nullptr;
  std::string mName;
  cl::Program mProgram;
  cl::Kernel mKernel;
  cl::Kernel mStayedKernel;
  cl::Kernel mInFrontKernel;

  bool mUploaded = false;
  int mVertexCount = 0;
  int mIterations = 0;
  std::vector<float> mOmega;  // one per iteration
  float mCompression = 1.0f;
  cl::Buffer mStart, mOther, mLower, mUpper, mShare, mStep;
  cl_util::GrowingBuffer mPositions{CL_MEM_READ_WRITE};  // F x 3V (limit() on host memory)
  cl_util::GrowingBuffer mScratch{CL_MEM_READ_WRITE};    // F x 3V, the other half of the ping-pong
  cl_util::GrowingBuffer mPlanes{CL_MEM_READ_ONLY};      // F x 4V (limit() on host memory)
  cl_util::GrowingBuffer mMarks{CL_MEM_READ_WRITE};      // F x V (limit() on host memory)
  cl_util::GrowingBuffer mStartPositions{CL_MEM_READ_WRITE};  // F x 3V, before (marks)
};

}  // namespace

std::unique_ptr<StrainLimitBackend> makeClStrainLimit(const cl_util::ClTarget& target) {
  return std::make_unique<ClStrainLimit>(target);
}

std::unique_ptr<StrainLimitBackend> makeClStrainLimit(const cl::Context& context,
                                                      const cl::Device& device,
                                                      const cl::CommandQueue& queue) {
  return makeClStrainLimit(cl_util::ClTarget{context, device, queue});
}

}  // namespace drivenshape
