// The OpenCL backend of the correction stage: the host candidate search (shared with the host
// backend), then kernels/closest.cl for the exact choice and kernels/transfer.cl for the
// local-frame transfer. One program holds both kernels; it is built once per backend.

#include <algorithm>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/correction.h>
#include <drivenshape/error.h>
#include <drivenshape_kernels/closest_cl.h>
#include <drivenshape_kernels/correction_types_cl.h>
#include <drivenshape_kernels/transfer_cl.h>

#include <correction_types.h>
#include <shared_types.h>

#include "candidates.h"
#include "cl_program.h"

namespace drivenshape {
namespace {

static_assert(sizeof(SurfaceHit) == sizeof(DsSurfaceHit), "SurfaceHit must match DsSurfaceHit");
static_assert(offsetof(SurfaceHit, triangle) == offsetof(DsSurfaceHit, triangle) &&
                  offsetof(SurfaceHit, u) == offsetof(DsSurfaceHit, u) &&
                  offsetof(SurfaceHit, v) == offsetof(DsSurfaceHit, v) &&
                  offsetof(SurfaceHit, distance2) == offsetof(DsSurfaceHit, distance2),
              "SurfaceHit must match DsSurfaceHit field by field");

bool hasFp64(const cl::Device& device) {
  const std::string extensions = device.getInfo<CL_DEVICE_EXTENSIONS>();
  return extensions.find("cl_khr_fp64") != std::string::npos;
}

/// A device buffer that grows to the largest size asked for and is then reused.
class GrowingBuffer {
 public:
  explicit GrowingBuffer(cl_mem_flags flags) : mFlags(flags) {}

  cl::Buffer& reserve(const cl::Context& context, std::size_t bytes) {
    bytes = std::max<std::size_t>(bytes, 16);
    if (bytes > mBytes) {
      mBuffer = cl::Buffer(context, mFlags, bytes);
      mBytes = bytes;
    }
    return mBuffer;
  }

 private:
  cl_mem_flags mFlags;
  cl::Buffer mBuffer;
  std::size_t mBytes = 0;
};

class ClClosest final : public ClosestBackend {
 public:
  ClClosest(const cl::Context& context, const cl::Device& device, const cl::CommandQueue& queue,
            const ClosestOptions& options)
      : mContext(context), mDevice(device), mQueue(queue), mSearch(options.threads) {
    mDouble = !options.forceSinglePrecision && hasFp64(device);
    std::vector<std::string> defines;
    if (mDouble) {
      defines.push_back("DS_USE_DOUBLE");
    }
    mProgram = cl_util::buildProgram(
        context, device,
        {{kernels::kCorrectionTypesSourceName, kernels::kCorrectionTypesSource},
         {kernels::kClosestSourceName, kernels::kClosestSource},
         {kernels::kTransferSourceName, kernels::kTransferSource}},
        defines);
    cl_util::guard("creating the correction kernels", [&] {
      mClosestKernel = cl::Kernel(mProgram, "dsClosest");
      mTransferKernel = cl::Kernel(mProgram, "dsTransfer");
      mName = device.getInfo<CL_DEVICE_NAME>();
    });
  }

  std::string name() const override { return mName; }

  void setSurface(const Mesh& driver, const BindingMask& mask) override {
    mSearch.setSurface(driver, mask);
    const std::vector<std::int32_t>& triangles = mSearch.triangles();
    cl_util::guard("uploading the driver triangles", [&] {
      mTriangles = cl::Buffer(mContext, CL_MEM_READ_ONLY, triangles.size() * sizeof(std::int32_t));
      mQueue.enqueueWriteBuffer(mTriangles, CL_TRUE, 0, triangles.size() * sizeof(std::int32_t),
                                triangles.data());
    });
  }

  void closest(int frameCount, const float* poses, const float* points, SurfaceHit* hits) override {
    mSearch.checkChunk("closest triangle", frameCount, hits != nullptr);
    mSearch.find(frameCount, poses, points, mCandidates);
    if (frameCount == 0 || mSearch.pointCount() == 0) {
      return;
    }
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    const std::size_t poseBytes =
        static_cast<std::size_t>(frameCount) * 3 * mSearch.vertexCount() * sizeof(float);
    const std::size_t pointBytes = items * 3 * sizeof(float);
    const double scale2 = mSearch.sceneScale() * mSearch.sceneScale();

    DsClosestParams params{};
    params.frameCount = frameCount;
    params.pointCount = mSearch.pointCount();
    params.vertexCount = mSearch.vertexCount();
    params.triangleCount = mSearch.triangleCount();
    params.tieRelative =
        static_cast<float>(mDouble ? DS_TIE_RELATIVE_DOUBLE : DS_TIE_RELATIVE_SINGLE);
    params.tieAbsolute =
        static_cast<float>((mDouble ? DS_TIE_SCALE2_DOUBLE : DS_TIE_SCALE2_SINGLE) * scale2);

    cl_util::guard("running the closest-triangle kernel", [&] {
      cl::Buffer& posesBuffer = mPoses.reserve(mContext, poseBytes);
      cl::Buffer& pointsBuffer = mPoints.reserve(mContext, pointBytes);
      cl::Buffer& startBuffer =
          mStart.reserve(mContext, mCandidates.start.size() * sizeof(std::int32_t));
      cl::Buffer& candidateBuffer = mCandidateTriangles.reserve(
          mContext, mCandidates.triangles.size() * sizeof(std::int32_t));
      cl::Buffer& hitBuffer = mHits.reserve(mContext, items * sizeof(SurfaceHit));
      mQueue.enqueueWriteBuffer(posesBuffer, CL_TRUE, 0, poseBytes, poses);
      mQueue.enqueueWriteBuffer(pointsBuffer, CL_TRUE, 0, pointBytes, points);
      mQueue.enqueueWriteBuffer(startBuffer, CL_TRUE, 0,
                                mCandidates.start.size() * sizeof(std::int32_t),
                                mCandidates.start.data());
      mQueue.enqueueWriteBuffer(candidateBuffer, CL_TRUE, 0,
                                mCandidates.triangles.size() * sizeof(std::int32_t),
                                mCandidates.triangles.data());
      mClosestKernel.setArg(0, posesBuffer);
      mClosestKernel.setArg(1, mTriangles);
      mClosestKernel.setArg(2, pointsBuffer);
      mClosestKernel.setArg(3, startBuffer);
      mClosestKernel.setArg(4, candidateBuffer);
      mClosestKernel.setArg(5, hitBuffer);
      mClosestKernel.setArg(6, sizeof(params), &params);
      mQueue.enqueueNDRangeKernel(mClosestKernel, cl::NullRange,
                                  cl::NDRange(cl_util::roundUp(items, DS_LOCAL_SIZE)),
                                  cl::NDRange(DS_LOCAL_SIZE));
      mQueue.enqueueReadBuffer(hitBuffer, CL_TRUE, 0, items * sizeof(SurfaceHit), hits);
    });
  }

  void transfer(int frameCount, const SurfaceHit* hits, const float* fromPoses,
                const float* toPoses, const float* points, float* out) override {
    correction::checkTransfer(mSearch, frameCount, hits, fromPoses, toPoses, points, out);
    if (frameCount == 0 || mSearch.pointCount() == 0) {
      return;
    }
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    const std::size_t poseBytes =
        static_cast<std::size_t>(frameCount) * 3 * mSearch.vertexCount() * sizeof(float);
    const std::size_t pointBytes = items * 3 * sizeof(float);
    DsTransferParams params{};
    params.frameCount = frameCount;
    params.pointCount = mSearch.pointCount();
    params.vertexCount = mSearch.vertexCount();
    params.triangleCount = mSearch.triangleCount();

    cl_util::guard("running the transfer kernel", [&] {
      cl::Buffer& hitBuffer = mHits.reserve(mContext, items * sizeof(SurfaceHit));
      cl::Buffer& fromBuffer = mPoses.reserve(mContext, poseBytes);
      cl::Buffer& toBuffer = mToPoses.reserve(mContext, poseBytes);
      cl::Buffer& pointsBuffer = mPoints.reserve(mContext, pointBytes);
      cl::Buffer& outBuffer = mOut.reserve(mContext, pointBytes);
      mQueue.enqueueWriteBuffer(hitBuffer, CL_TRUE, 0, items * sizeof(SurfaceHit), hits);
      mQueue.enqueueWriteBuffer(fromBuffer, CL_TRUE, 0, poseBytes, fromPoses);
      mQueue.enqueueWriteBuffer(toBuffer, CL_TRUE, 0, poseBytes, toPoses);
      mQueue.enqueueWriteBuffer(pointsBuffer, CL_TRUE, 0, pointBytes, points);
      mTransferKernel.setArg(0, hitBuffer);
      mTransferKernel.setArg(1, fromBuffer);
      mTransferKernel.setArg(2, toBuffer);
      mTransferKernel.setArg(3, mTriangles);
      mTransferKernel.setArg(4, pointsBuffer);
      mTransferKernel.setArg(5, outBuffer);
      mTransferKernel.setArg(6, sizeof(params), &params);
      mQueue.enqueueNDRangeKernel(mTransferKernel, cl::NullRange,
                                  cl::NDRange(cl_util::roundUp(items, DS_LOCAL_SIZE)),
                                  cl::NDRange(DS_LOCAL_SIZE));
      mQueue.enqueueReadBuffer(outBuffer, CL_TRUE, 0, pointBytes, out);
    });
  }

 private:
  cl::Context mContext;
  cl::Device mDevice;
  cl::CommandQueue mQueue;
  bool mDouble = false;
  std::string mName;
  cl::Program mProgram;
  cl::Kernel mClosestKernel;
  cl::Kernel mTransferKernel;
  correction::CandidateSearch mSearch;
  correction::CandidateTable mCandidates;
  cl::Buffer mTriangles;
  GrowingBuffer mPoses{CL_MEM_READ_ONLY};
  GrowingBuffer mToPoses{CL_MEM_READ_ONLY};
  GrowingBuffer mPoints{CL_MEM_READ_ONLY};
  GrowingBuffer mStart{CL_MEM_READ_ONLY};
  GrowingBuffer mCandidateTriangles{CL_MEM_READ_ONLY};
  GrowingBuffer mHits{CL_MEM_READ_WRITE};
  GrowingBuffer mOut{CL_MEM_WRITE_ONLY};
};

}  // namespace

std::unique_ptr<ClosestBackend> makeClClosest(const cl::Context& context, const cl::Device& device,
                                              const cl::CommandQueue& queue,
                                              const ClosestOptions& options) {
  return std::make_unique<ClClosest>(context, device, queue, options);
}

}  // namespace drivenshape
