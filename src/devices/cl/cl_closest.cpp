// The OpenCL backend of the correction stage: the host candidate search (shared with the host
// backend), then kernels/closest.cl for the exact choice and kernels/transfer.cl for the
// local-frame transfer and rebuild, kernels/resolve.cl for the penetration resolution. One
// program holds all the kernels; it is built once per backend.

#include <algorithm>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/correction.h>
#include <drivenshape/error.h>
#include <drivenshape_kernels/bvh_cl.h>
#include <drivenshape_kernels/closest_cl.h>
#include <drivenshape_kernels/correction_types_cl.h>
#include <drivenshape_kernels/resolve_cl.h>
#include <drivenshape_kernels/transfer_cl.h>

#include <correction_types.h>
#include <shared_types.h>

#include "bvh.h"
#include "candidates.h"
#include "cl_program.h"
#include "surface_features.h"

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

class ClClosest final : public ClosestBackend {
 public:
  ClClosest(const cl_util::ClTarget& target, const ClosestOptions& options)
      : mContext(target.context),
        mDevice(target.device),
        mQueue(target.queue),
        mTransfers(target.transfers),
        mUseBvh(options.deviceSearch == ClosestOptions::DeviceSearch::kBvh),
        mSearch(options.threads) {
    mDouble = !options.forceSinglePrecision && hasFp64(mDevice);
    std::vector<std::string> defines;
    if (mDouble) {
      defines.push_back("DS_USE_DOUBLE");
    }
    mProgram = cl_util::buildProgram(
        target,
        {{kernels::kCorrectionTypesSourceName, kernels::kCorrectionTypesSource},
         {kernels::kClosestSourceName, kernels::kClosestSource},
         {kernels::kTransferSourceName, kernels::kTransferSource},
         {kernels::kResolveSourceName, kernels::kResolveSource},
         {kernels::kBvhSourceName, kernels::kBvhSource}},
        defines);
    cl_util::guard("creating the correction kernels", [&] {
      mClosestKernel = cl::Kernel(mProgram, "dsClosest");
      mTransferKernel = cl::Kernel(mProgram, "dsTransfer");
      mRebuildKernel = cl::Kernel(mProgram, "dsRebuild");
      mResolveKernel = cl::Kernel(mProgram, "dsResolve");
      mRefitKernel = cl::Kernel(mProgram, "dsBvhRefit");
      mBvhKernel = cl::Kernel(mProgram, "dsBvhClosest");
      mName = mDevice.getInfo<CL_DEVICE_NAME>();
    });
  }

  std::string name() const override { return mName; }

  void setSurface(const Mesh& driver, const BindingMask& mask) override {
    mSearch.setSurface(driver, mask);
    const std::vector<std::int32_t>& triangles = mSearch.triangles();
    cl_util::guard("uploading the driver triangles", [&] {
      mTriangles = cl::Buffer(mContext, CL_MEM_READ_ONLY, triangles.size() * sizeof(std::int32_t));
      cl_util::upload(mQueue, mTransfers, mTriangles, CL_TRUE, 0,
                      triangles.size() * sizeof(std::int32_t), triangles.data());
      const correction::FeatureTables features = correction::buildFeatureTables(
          triangles.data(), mSearch.triangleCount(), mSearch.vertexCount());
      mEdgeStart = upload(features.edgeStart);
      mEdgeTriangles = upload(features.edgeTriangles);
      mVertexStart = upload(features.vertexStart);
      mVertexTriangles = upload(features.vertexTriangles);
      mBvh = correction::buildBvh(driver, mask, kLeafSize);
      mNodes = uploadBytes(mBvh.nodes.data(), mBvh.nodes.size() * sizeof(DsBvhNode));
      mLeafTriangles = upload(mBvh.leafTriangles);
      mPointRoot = upload(mBvh.pointRoot);
      mSeeds = upload(std::vector<std::int32_t>(mBvh.pointRoot.size(), 0));
      mSeeded = false;
    });
  }

  void closest(int frameCount, const float* poses, const float* points, SurfaceHit* hits) override {
    mSearch.checkChunk("closest triangle", frameCount, hits != nullptr);
    if (mUseBvh) {
      closestBvh(frameCount, poses, points, hits);
      return;
    }
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
      const cl::Buffer& posesBuffer = posesOnDevice(mPoses, poses, poseBytes);
      cl::Buffer& pointsBuffer = mPoints.reserve(mContext, pointBytes);
      cl::Buffer& startBuffer =
          mStart.reserve(mContext, mCandidates.start.size() * sizeof(std::int32_t));
      cl::Buffer& candidateBuffer = mCandidateTriangles.reserve(
          mContext, mCandidates.triangles.size() * sizeof(std::int32_t));
      cl::Buffer& hitBuffer = mHits.reserve(mContext, items * sizeof(SurfaceHit));
      cl_util::upload(mQueue, mTransfers, pointsBuffer, CL_TRUE, 0, pointBytes, points);
      cl_util::upload(mQueue, mTransfers, startBuffer, CL_TRUE, 0,
                      mCandidates.start.size() * sizeof(std::int32_t), mCandidates.start.data());
      cl_util::upload(mQueue, mTransfers, candidateBuffer, CL_TRUE, 0,
                      mCandidates.triangles.size() * sizeof(std::int32_t),
                      mCandidates.triangles.data());
      cl_util::setArgs(mClosestKernel, posesBuffer, mTriangles, pointsBuffer, startBuffer,
                       candidateBuffer, hitBuffer, params);
      cl_util::enqueue1d(mQueue, mClosestKernel, items, DS_LOCAL_SIZE);
      cl_util::download(mQueue, mTransfers, hitBuffer, CL_TRUE, 0, items * sizeof(SurfaceHit),
                        hits);
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
    const DsTransferParams params = transferParams(frameCount);

    cl_util::guard("running the transfer kernel", [&] {
      cl::Buffer& hitBuffer = mHits.reserve(mContext, items * sizeof(SurfaceHit));
      cl::Buffer& fromBuffer = mPoses.reserve(mContext, poseBytes);
      const cl::Buffer& toBuffer = posesOnDevice(mToPoses, toPoses, poseBytes);
      cl::Buffer& pointsBuffer = mPoints.reserve(mContext, pointBytes);
      cl::Buffer& outBuffer = mOut.reserve(mContext, pointBytes);
      cl_util::upload(mQueue, mTransfers, hitBuffer, CL_TRUE, 0, items * sizeof(SurfaceHit), hits);
      cl_util::upload(mQueue, mTransfers, fromBuffer, CL_TRUE, 0, poseBytes, fromPoses);
      cl_util::upload(mQueue, mTransfers, pointsBuffer, CL_TRUE, 0, pointBytes, points);
      cl_util::setArgs(mTransferKernel, hitBuffer, fromBuffer, toBuffer, mTriangles, pointsBuffer,
                       outBuffer, params);
      cl_util::enqueue1d(mQueue, mTransferKernel, items, DS_LOCAL_SIZE);
      cl_util::download(mQueue, mTransfers, outBuffer, CL_TRUE, 0, pointBytes, out);
    });
  }

  void rebuild(int frameCount, const SurfaceHit* hits, const float* toPoses, const float* local,
               float* out) override {
    correction::checkRebuild(mSearch, frameCount, hits, toPoses, local, out);
    if (frameCount == 0 || mSearch.pointCount() == 0) {
      return;
    }
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    const std::size_t hitBytes =
        static_cast<std::size_t>(mSearch.pointCount()) * sizeof(SurfaceHit);
    const std::size_t poseBytes =
        static_cast<std::size_t>(frameCount) * 3 * mSearch.vertexCount() * sizeof(float);
    const std::size_t pointBytes = items * 3 * sizeof(float);
    const DsTransferParams params = transferParams(frameCount);

    cl_util::guard("running the rebuild kernel", [&] {
      cl::Buffer& hitBuffer = mHits.reserve(mContext, hitBytes);
      const cl::Buffer& toBuffer = posesOnDevice(mToPoses, toPoses, poseBytes);
      cl::Buffer& localBuffer = mPoints.reserve(mContext, pointBytes);
      cl::Buffer& outBuffer = mOut.reserve(mContext, pointBytes);
      cl_util::upload(mQueue, mTransfers, hitBuffer, CL_FALSE, 0, hitBytes, hits);
      cl_util::upload(mQueue, mTransfers, localBuffer, CL_FALSE, 0, pointBytes, local);
      cl_util::setArgs(mRebuildKernel, hitBuffer, toBuffer, mTriangles, localBuffer, outBuffer,
                       params);
      cl_util::enqueue1d(mQueue, mRebuildKernel, items, DS_LOCAL_SIZE);
      cl_util::download(mQueue, mTransfers, outBuffer, CL_TRUE, 0, pointBytes, out);
    });
  }

  void resolve(int frameCount, const float* poses, const SurfaceHit* hits, float offset,
               float* points, int* moved) override {
    correction::checkResolve(mSearch, frameCount, poses, hits, offset, points);
    if (frameCount == 0) {
      return;
    }
    if (mSearch.pointCount() == 0) {
      std::fill(moved, moved + (moved != nullptr ? frameCount : 0), 0);
      return;
    }
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    const std::size_t poseBytes =
        static_cast<std::size_t>(frameCount) * 3 * mSearch.vertexCount() * sizeof(float);
    const std::size_t pointBytes = items * 3 * sizeof(float);
    const std::size_t countBytes = static_cast<std::size_t>(frameCount) * sizeof(cl_int);
    DsResolveParams params{};
    params.frameCount = frameCount;
    params.pointCount = mSearch.pointCount();
    params.vertexCount = mSearch.vertexCount();
    params.triangleCount = mSearch.triangleCount();
    params.offset = offset;

    cl_util::guard("running the penetration-resolution kernel", [&] {
      const cl::Buffer& posesBuffer = posesOnDevice(mPoses, poses, poseBytes);
      cl::Buffer& hitBuffer = mHits.reserve(mContext, items * sizeof(SurfaceHit));
      cl::Buffer& pointsBuffer = mOut.reserve(mContext, pointBytes);
      cl::Buffer& countBuffer = mCounts.reserve(mContext, countBytes);
      cl_util::upload(mQueue, mTransfers, hitBuffer, CL_FALSE, 0, items * sizeof(SurfaceHit), hits);
      cl_util::upload(mQueue, mTransfers, pointsBuffer, CL_FALSE, 0, pointBytes, points);
      mQueue.enqueueFillBuffer(countBuffer, cl_int(0), 0, countBytes);
      cl_util::setArgs(mResolveKernel, posesBuffer, mTriangles, mEdgeStart, mEdgeTriangles,
                       mVertexStart, mVertexTriangles, hitBuffer, pointsBuffer, countBuffer,
                       params);
      cl_util::enqueue1d(mQueue, mResolveKernel, items, DS_LOCAL_SIZE);
      cl_util::download(mQueue, mTransfers, pointsBuffer, CL_TRUE, 0, pointBytes, points);
      std::vector<cl_int> counts(static_cast<std::size_t>(frameCount));
      cl_util::download(mQueue, mTransfers, countBuffer, CL_TRUE, 0, countBytes, counts.data());
      if (moved != nullptr) {
        std::copy(counts.begin(), counts.end(), moved);
      }
    });
  }

  void keepPoses(int frameCount, const float* poses) override {
    mKeptHost = nullptr;
    const std::size_t bytes =
        static_cast<std::size_t>(frameCount) * 3 * mSearch.vertexCount() * sizeof(float);
    if (frameCount <= 0 || poses == nullptr) {
      return;
    }
    cl_util::guard("uploading the batch's driver poses", [&] {
      cl::Buffer& buffer = mKeptPoses.reserve(mContext, bytes);
      cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, bytes, poses);
    });
    mKeptHost = poses;
    mKeptBytes = bytes;
  }

  void releasePoses() override { mKeptHost = nullptr; }

 private:
  /// The device copy of `poses` (`bytes` long): the kept one (keepPoses) when it is that
  /// block, else `scratch` after a blocking upload.
  const cl::Buffer& posesOnDevice(cl_util::GrowingBuffer& scratch, const float* poses,
                                  std::size_t bytes) {
    if (poses == mKeptHost && bytes == mKeptBytes) {
      return mKeptPoses.reserve(mContext, bytes);
    }
    cl::Buffer& buffer = scratch.reserve(mContext, bytes);
    cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, bytes, poses);
    return buffer;
  }

  /// The sizes the transfer and rebuild kernels share.
  DsTransferParams transferParams(int frameCount) const {
    DsTransferParams params{};
    params.frameCount = frameCount;
    params.pointCount = mSearch.pointCount();
    params.vertexCount = mSearch.vertexCount();
    params.triangleCount = mSearch.triangleCount();
    return params;
  }

  /// At most this many triangles per BVH leaf (measured on W1: 4 and 8 are within noise).
  static constexpr int kLeafSize = 4;

  /// ClosestBackend::closest through the BVH (see src/correction/bvh.cpp and kernels/bvh.cl).
  void closestBvh(int frameCount, const float* poses, const float* points, SurfaceHit* hits) {
    mSearch.checkChunk("closest triangle", frameCount, poses != nullptr && points != nullptr);
    correction::checkFinite("closest triangle", "driver vertex", frameCount, mSearch.vertexCount(),
                            poses);
    correction::checkFinite("closest triangle", "driven point", frameCount, mSearch.pointCount(),
                            points);
    const int pointCount = mSearch.pointCount();
    if (frameCount == 0 || pointCount == 0) {
      return;
    }
    const int vertexCount = mSearch.vertexCount();
    const int nodeCount = static_cast<int>(mBvh.nodes.size());
    const std::size_t items = static_cast<std::size_t>(frameCount) * pointCount;
    const std::size_t poseBytes =
        static_cast<std::size_t>(frameCount) * 3 * vertexCount * sizeof(float);
    const std::size_t pointBytes = items * 3 * sizeof(float);
    const std::size_t boxBytes = static_cast<std::size_t>(frameCount) *
                                 static_cast<std::size_t>(nodeCount) * 6 * sizeof(float);
    const double scale2 = mSearch.sceneScale() * mSearch.sceneScale();
    const double prune = mDouble ? DS_PRUNE_RELATIVE_DOUBLE : DS_PRUNE_RELATIVE_SINGLE;

    DsBvhQueryParams params{};
    params.frameCount = frameCount;
    params.pointCount = pointCount;
    params.vertexCount = vertexCount;
    params.nodeCount = nodeCount;
    params.tieRelative =
        static_cast<float>(mDouble ? DS_TIE_RELATIVE_DOUBLE : DS_TIE_RELATIVE_SINGLE);
    params.tieAbsolute =
        static_cast<float>((mDouble ? DS_TIE_SCALE2_DOUBLE : DS_TIE_SCALE2_SINGLE) * scale2);
    params.pruneRelative = static_cast<float>(prune);
    params.pruneAbsolute = static_cast<float>(prune * scale2);

    if (!mSeeded) {
      correction::seedTriangles(mBvh, mSearch.triangles().data(), poses, points, mSeedHost);
      cl_util::guard("uploading the closest-triangle warm start", [&] {
        cl_util::upload(mQueue, mTransfers, mSeeds, CL_TRUE, 0,
                        mSeedHost.size() * sizeof(std::int32_t), mSeedHost.data());
      });
      mSeeded = true;
    }

    cl_util::guard("running the closest-triangle kernels", [&] {
      const cl::Buffer& posesBuffer = posesOnDevice(mPoses, poses, poseBytes);
      cl::Buffer& pointsBuffer = mPoints.reserve(mContext, pointBytes);
      cl::Buffer& boxBuffer = mBoxes.reserve(mContext, boxBytes);
      cl::Buffer& hitBuffer = mHits.reserve(mContext, items * sizeof(SurfaceHit));
      cl_util::upload(mQueue, mTransfers, pointsBuffer, CL_FALSE, 0, pointBytes, points);
      DsBvhRefitParams refit{};
      refit.frameCount = frameCount;
      refit.vertexCount = vertexCount;
      refit.nodeCount = nodeCount;
      // Arguments 0-3 stay; the level's range (argument 4) changes per launch.
      cl_util::setArgs(mRefitKernel, posesBuffer, mNodes, mLeafTriangles, boxBuffer, refit);
      for (int level = mBvh.depth() - 1; level >= 0; --level) {
        refit.levelFirst = mBvh.levelStart[static_cast<std::size_t>(level)];
        refit.levelCount = mBvh.levelStart[static_cast<std::size_t>(level) + 1] - refit.levelFirst;
        mRefitKernel.setArg(4, refit);
        const std::size_t work = static_cast<std::size_t>(frameCount) * refit.levelCount;
        cl_util::enqueue1d(mQueue, mRefitKernel, work, DS_LOCAL_SIZE);
      }
      cl_util::setArgs(mBvhKernel, posesBuffer, mTriangles, mNodes, mLeafTriangles, boxBuffer,
                       pointsBuffer, mPointRoot, mSeeds, hitBuffer, params);
      cl_util::enqueue1d(mQueue, mBvhKernel, items, DS_LOCAL_SIZE);
      cl_util::download(mQueue, mTransfers, hitBuffer, CL_TRUE, 0, items * sizeof(SurfaceHit),
                        hits);
      // The next chunk starts from this chunk's last frame (a warm start only; see bvh.cpp).
      const SurfaceHit* last = hits + (items - static_cast<std::size_t>(pointCount));
      for (int i = 0; i < pointCount; ++i) {
        mSeedHost[static_cast<std::size_t>(i)] = last[i].triangle;
      }
      cl_util::upload(mQueue, mTransfers, mSeeds, CL_TRUE, 0,
                      mSeedHost.size() * sizeof(std::int32_t), mSeedHost.data());
    });
  }

  cl::Buffer uploadBytes(const void* data, std::size_t bytes) {
    cl::Buffer buffer(mContext, CL_MEM_READ_ONLY, std::max<std::size_t>(bytes, 16));
    if (bytes > 0) {
      cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, bytes, data);
    }
    return buffer;
  }

  /// A read-only device copy of a host table (at least one element, so empty tables work).
  cl::Buffer upload(const std::vector<std::int32_t>& table) {
    const std::size_t bytes = std::max<std::size_t>(table.size(), 1) * sizeof(std::int32_t);
    cl::Buffer buffer(mContext, CL_MEM_READ_ONLY, bytes);
    if (!table.empty()) {
      cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, table.size() * sizeof(std::int32_t),
                      table.data());
    }
    return buffer;
  }

  cl::Context mContext;
  cl::Device mDevice;
  cl::CommandQueue mQueue;
  cl_util::Transfers* mTransfers = nullptr;
  bool mDouble = false;
  bool mUseBvh = true;
  std::string mName;
  cl::Program mProgram;
  cl::Kernel mClosestKernel;
  cl::Kernel mTransferKernel;
  cl::Kernel mRebuildKernel;
  cl::Kernel mResolveKernel;
  cl::Kernel mRefitKernel;
  cl::Kernel mBvhKernel;
  correction::CandidateSearch mSearch;
  correction::CandidateTable mCandidates;
  cl::Buffer mTriangles;
  cl::Buffer mEdgeStart;
  cl::Buffer mEdgeTriangles;
  cl::Buffer mVertexStart;
  cl::Buffer mVertexTriangles;
  correction::BvhTables mBvh;
  cl::Buffer mNodes;
  cl::Buffer mLeafTriangles;
  cl::Buffer mPointRoot;
  cl::Buffer mSeeds;
  std::vector<std::int32_t> mSeedHost;
  bool mSeeded = false;
  cl_util::GrowingBuffer mBoxes{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mPoses{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mToPoses{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mPoints{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mStart{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mCandidateTriangles{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mHits{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mOut{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mCounts{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mKeptPoses{CL_MEM_READ_ONLY};  // keepPoses(): F x 3Vp
  const float* mKeptHost = nullptr;                     // the host block it copies, or null
  std::size_t mKeptBytes = 0;
};

}  // namespace

std::unique_ptr<ClosestBackend> makeClClosest(const cl_util::ClTarget& target,
                                              const ClosestOptions& options) {
  return std::make_unique<ClClosest>(target, options);
}

std::unique_ptr<ClosestBackend> makeClClosest(const cl::Context& context, const cl::Device& device,
                                              const cl::CommandQueue& queue,
                                              const ClosestOptions& options) {
  return makeClClosest(cl_util::ClTarget{context, device, queue}, options);
}

}  // namespace drivenshape
