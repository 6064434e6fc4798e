// SPDX-License-Identifier: Apache-2.0
// The OpenCL backend of the correction stage: the host candidate search (shared with the host
// backend), then kernels/closest.cl for the exact choice and kernels/transfer.cl for the
// local-frame transfer and rebuild, kernels/resolve.cl for the penetration resolution. One
// program holds all the kernels; it is built once per backend.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape_kernels/bvh_cl.h>
#include <drivenshape_kernels/certificate_cl.h>
#include <drivenshape_kernels/closest_cl.h>
#include <drivenshape_kernels/correction_types_cl.h>
#include <drivenshape_kernels/resolve_cl.h>
#include <drivenshape_kernels/transfer_cl.h>
#include "closest.h"

#include <correction_types.h>
#include <shared_types.h>

#include "bvh.h"
#include "candidates.h"
#include "certificate.h"
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

/// The device side of a view array (see ClClosest::onDevice).
std::unique_ptr<DeviceStorage> storage(const cl_util::ClTarget& target) {
  return std::make_unique<cl_util::ClStorage>(target.context, target.queue, target.transfers);
}

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
        mSearch(options.threads),
        mViewPoses(storage(target)),
        mViewToPoses(storage(target)),
        mViewPoints(storage(target)),
        mViewHits(storage(target)),
        mViewOut(storage(target)),
        mViewAnswered(storage(target)) {
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
         {kernels::kBvhSourceName, kernels::kBvhSource},
         {kernels::kResolveSourceName, kernels::kResolveSource},
         {kernels::kCertificateSourceName, kernels::kCertificateSource}},
        defines);
    cl_util::guard("creating the correction kernels", [&] {
      mClosestKernel = cl::Kernel(mProgram, "dsClosest");
      mTransferKernel = cl::Kernel(mProgram, "dsTransfer");
      mRebuildKernel = cl::Kernel(mProgram, "dsRebuild");
      mResolveKernel = cl::Kernel(mProgram, "dsResolve");
      mCountInsideKernel = cl::Kernel(mProgram, "dsCountInside");
      mRefitKernel = cl::Kernel(mProgram, "dsBvhRefit");
      mBvhKernel = cl::Kernel(mProgram, "dsBvhClosest");
      mBvhListKernel = cl::Kernel(mProgram, "dsBvhClosestList");
      mConeKernel = cl::Kernel(mProgram, "dsCertRefitCones");
      mCertCheckKernel = cl::Kernel(mProgram, "dsCertCheck");
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
      mSeeds = uploadBytes(std::vector<SurfaceHit>(mBvh.pointRoot.size()).data(),
                           mBvh.pointRoot.size() * sizeof(SurfaceHit));
      mSeeded = false;
      mSides = uploadBytes(nullptr, 0);
      mSided = false;
      mCertifiable = correction::certifiable(mBvh, mSearch.triangleCount());
      mNodeTriangle = upload(correction::nodeTriangles(mBvh));
      mBoxesOf = mConesOf = Refit{};
    });
  }

  void setExitFade(float fade) override {
    correction::checkExitFade(fade);
    mFade = fade;
  }

  void setSides(const std::vector<std::int8_t>& sides) override {
    correction::checkSides(sides, mSearch.pointCount());
    cl_util::guard("uploading the side table", [&] {
      mSides = uploadBytes(sides.data(), sides.size());
      mSided = !sides.empty();
    });
  }

  void closest(int frameCount, const float* poses, const float* points, SurfaceHit* hits) override {
    mSearch.checkChunk("closest triangle", frameCount,
                       poses != nullptr && points != nullptr && hits != nullptr);
    if (!mUseBvh) {
      closestCandidates(frameCount, poses, points, hits);
      return;
    }
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    mViewPoses.view(poses, static_cast<std::size_t>(frameCount) * poseValues());
    mViewPoints.view(points, items * 3);
    mViewHits.view(hits, items);
    checkInputs("closest triangle", frameCount, &mViewPoses, &mViewPoints, nullptr, 0);
    closestBvh(frameCount, mViewPoses, mViewPoints, mViewHits);
    mViewHits.read<SurfaceHit>();  // into `hits`
  }

  void transfer(int frameCount, const SurfaceHit* hits, const float* fromPoses,
                const float* toPoses, const float* points, float* out) override {
    correction::checkTransfer(mSearch, frameCount, hits, fromPoses, toPoses, points, out);
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    mViewHits.view(hits, items);
    mViewPoses.view(fromPoses, static_cast<std::size_t>(frameCount) * poseValues());
    mViewToPoses.view(toPoses, static_cast<std::size_t>(frameCount) * poseValues());
    mViewPoints.view(points, items * 3);
    mViewOut.view(out, items * 3);
    transferOnDevice(frameCount, mViewHits, mViewPoses, mViewToPoses, mViewPoints, mViewOut);
    mViewOut.read<float>();  // into `out`
  }

  void rebuild(int frameCount, const SurfaceHit* hits, const float* toPoses, const float* local,
               float* out) override {
    correction::checkRebuild(mSearch, frameCount, hits, toPoses, local, out);
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    mViewHits.view(hits, static_cast<std::size_t>(mSearch.pointCount()));
    mViewToPoses.view(toPoses, static_cast<std::size_t>(frameCount) * poseValues());
    mViewPoints.view(local, items * 3);
    mViewOut.view(out, items * 3);
    rebuildOnDevice(frameCount, mViewHits, mViewToPoses, mViewPoints, mViewOut);
    mViewOut.read<float>();
  }

  void resolve(int frameCount, const float* poses, const SurfaceHit* hits, float offset,
               float* points, int* moved) override {
    correction::checkResolve(mSearch, frameCount, poses, hits, offset, points);
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    mViewPoses.view(poses, static_cast<std::size_t>(frameCount) * poseValues());
    mViewHits.view(hits, items);
    mViewOut.view(points, items * 3);
    resolveOnDevice(frameCount, mViewPoses, mViewHits, offset, mViewOut, moved);
    mViewOut.read<float>();
  }

  void countInside(int frameCount, DeviceArray& poses, DeviceArray& hits, DeviceArray& points,
                   int* inside) override {
    mSearch.checkChunk("inside count", frameCount, inside != nullptr);
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    checkInputs("inside count", frameCount, &poses, &points, &hits, items);
    std::fill(inside, inside + frameCount, 0);
    if (items == 0) {
      return;
    }
    DeviceArray& posesOn = onDevice(poses, mViewPoses);
    DeviceArray& hitsOn = onDevice(hits, mViewHits);
    DeviceArray& pointsOn = onDevice(points, mViewPoints);
    launchSigned(mCountInsideKernel, frameCount, posesOn, hitsOn, cl_util::readBuffer(pointsOn),
                 0.0f, 0.0f, inside, "running the inside-count kernel");
  }

  void closestBlock(int frameCount, DeviceArray& poses, DeviceArray& points,
                    DeviceArray& hits) override {
    if (!mUseBvh) {
      ClosestBackend::closestBlock(frameCount, poses, points, hits);
      return;
    }
    mSearch.checkChunk("closest triangle", frameCount, true);
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    checkInputs("closest triangle", frameCount, &poses, &points, nullptr, 0);
    DeviceArray& out = outputOnDevice(hits, mViewHits, items * sizeof(SurfaceHit), false);
    closestBvh(frameCount, onDevice(poses, mViewPoses), onDevice(points, mViewPoints), out);
    finishOutput(out, mViewHits);
  }

  void closestOrClearBlock(int frameCount, DeviceArray& poses, DeviceArray& points, float clearance,
                           DeviceArray& hits, int* cleared, DeviceArray* answered,
                           bool keep) override {
    if (!mUseBvh || !mCertifiable) {
      ClosestBackend::closestOrClearBlock(frameCount, poses, points, clearance, hits, cleared,
                                          answered, keep);
      return;
    }
    mSearch.checkChunk("closest triangle", frameCount, true);
    correction::checkOffset(clearance);
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    checkInputs("closest triangle", frameCount, &poses, &points, nullptr, 0);
    const bool kept = keep && answered != nullptr;
    std::vector<int> counts(static_cast<std::size_t>(frameCount), 0);
    if (items > 0) {
      DeviceArray& out = outputOnDevice(hits, mViewHits, items * sizeof(SurfaceHit), kept);
      DeviceArray* marks = nullptr;
      if (answered != nullptr) {
        marks = &outputOnDevice(*answered, mViewAnswered, items * sizeof(std::int32_t), kept);
      }
      clearOrSearch(frameCount, onDevice(poses, mViewPoses), onDevice(points, mViewPoints),
                    clearance, out, marks, kept, counts.data());
      finishOutput(out, mViewHits);
      if (marks != nullptr) {
        finishOutput(*marks, mViewAnswered);
      }
    }
    if (cleared != nullptr) {
      std::copy(counts.begin(), counts.end(), cleared);
    }
  }

  void transferBlock(int frameCount, DeviceArray& hits, DeviceArray& fromPoses,
                     DeviceArray& toPoses, DeviceArray& points, DeviceArray& out) override {
    mSearch.checkChunk("transfer", frameCount, true);
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    checkInputs("transfer", frameCount, &fromPoses, &points, &hits, items);
    checkInputs("transfer", frameCount, &toPoses, nullptr, nullptr, 0);
    DeviceArray& result = outputOnDevice(out, mViewOut, items * 3 * sizeof(float), false);
    transferOnDevice(frameCount, onDevice(hits, mViewHits), onDevice(fromPoses, mViewPoses),
                     onDevice(toPoses, mViewToPoses), onDevice(points, mViewPoints), result);
    finishOutput(result, mViewOut);
  }

  void rebuildBlock(int frameCount, DeviceArray& hits, DeviceArray& toPoses, DeviceArray& local,
                    DeviceArray& out) override {
    mSearch.checkChunk("rebuild", frameCount, true);
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    checkInputs("rebuild", frameCount, &toPoses, &local, nullptr, 0);
    if (frameCount > 0) {
      correction::checkHits("rebuild", mSearch.triangleCount(),
                            static_cast<std::size_t>(mSearch.pointCount()),
                            std::max(mSearch.pointCount(), 1), hits.hostIfCurrent<SurfaceHit>());
    }
    DeviceArray& result = outputOnDevice(out, mViewOut, items * 3 * sizeof(float), false);
    rebuildOnDevice(frameCount, onDevice(hits, mViewHits), onDevice(toPoses, mViewToPoses),
                    onDevice(local, mViewPoints), result);
    finishOutput(result, mViewOut);
  }

  void resolveBlock(int frameCount, DeviceArray& poses, DeviceArray& hits, float offset,
                    DeviceArray& points, int* moved) override {
    mSearch.checkChunk("penetration resolution", frameCount, true);
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    correction::checkOffset(offset);
    checkInputs("penetration resolution", frameCount, &poses, &points, &hits, items);
    DeviceArray& result = outputOnDevice(points, mViewOut, items * 3 * sizeof(float), true);
    resolveOnDevice(frameCount, onDevice(poses, mViewPoses), onDevice(hits, mViewHits), offset,
                    result, moved);
    finishOutput(result, mViewOut);
  }

 private:
  /// 3Vp: the floats of one pose.
  std::size_t poseValues() const { return 3 * static_cast<std::size_t>(mSearch.vertexCount()); }

  /// `array` itself when its device side is on this context; else `view` over its host copy
  /// (an array of another device, or of the host), uploaded by the kernel call that reads it.
  DeviceArray& onDevice(DeviceArray& array, DeviceArray& view) {
    if (cl_util::onContext(mContext, array)) {
      return array;
    }
    view.view(array.read<unsigned char>(), array.bytes());
    return view;
  }

  /// An output array as the kernels see it: `target` itself when it is on this context, else
  /// `view` over its host copy (`keep`: with its current values, for updates in place), which
  /// finishOutput() brings back. The caller sizes `target` (at least `bytes`).
  DeviceArray& outputOnDevice(DeviceArray& target, DeviceArray& view, std::size_t bytes,
                              bool keep) {
    if (target.bytes() < bytes) {
      DS_THROW(kInternal, "an output block of ", target.bytes(), " bytes was given for ", bytes);
    }
    if (cl_util::onContext(mContext, target)) {
      return target;
    }
    view.view(keep ? target.modify<unsigned char>() : target.write<unsigned char>(),
              target.bytes());
    return view;
  }
  /// Downloads an output that went through a view into its target's host copy.
  static void finishOutput(DeviceArray& used, DeviceArray& view) {
    if (&used == &view) {
      view.read<unsigned char>();
    }
  }

  /// The raw calls' NaN and range checks on the host copies that are current (see
  /// correction::checkFinite): poses F x 3Vp, points F x 3Vd, `hitCount` hits.
  void checkInputs(const char* stage, int frameCount, DeviceArray* poses, DeviceArray* points,
                   DeviceArray* hits, std::size_t hitCount) const {
    if (poses != nullptr) {
      correction::checkFinite(stage, "driver vertex", frameCount, mSearch.vertexCount(),
                              poses->hostIfCurrent<float>());
    }
    if (points != nullptr) {
      correction::checkFinite(stage, "driven point", frameCount, mSearch.pointCount(),
                              points->hostIfCurrent<float>());
    }
    if (hits != nullptr && hitCount > 0) {
      correction::checkHits(stage, mSearch.triangleCount(), hitCount,
                            std::max(mSearch.pointCount(), 1), hits->hostIfCurrent<SurfaceHit>());
    }
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

  /// ClosestBackend::closest with the host candidate lists (ClosestOptions::kCandidates).
  void closestCandidates(int frameCount, const float* poses, const float* points,
                         SurfaceHit* hits) {
    mSearch.find(frameCount, poses, points, mCandidates);
    if (frameCount == 0 || mSearch.pointCount() == 0) {
      return;
    }
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    const std::size_t poseBytes = static_cast<std::size_t>(frameCount) * poseValues() * 4;
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
      cl_util::upload(mQueue, mTransfers, posesBuffer, CL_TRUE, 0, poseBytes, poses);
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

  /// The BVH query's scalars for a chunk of `frameCount` frames.
  DsBvhQueryParams queryParams(int frameCount) const {
    const double scale2 = mSearch.sceneScale() * mSearch.sceneScale();
    const double prune = mDouble ? DS_PRUNE_RELATIVE_DOUBLE : DS_PRUNE_RELATIVE_SINGLE;
    DsBvhQueryParams params{};
    params.frameCount = frameCount;
    params.pointCount = mSearch.pointCount();
    params.vertexCount = mSearch.vertexCount();
    params.nodeCount = static_cast<int>(mBvh.nodes.size());
    params.tieRelative =
        static_cast<float>(mDouble ? DS_TIE_RELATIVE_DOUBLE : DS_TIE_RELATIVE_SINGLE);
    params.tieAbsolute =
        static_cast<float>((mDouble ? DS_TIE_SCALE2_DOUBLE : DS_TIE_SCALE2_SINGLE) * scale2);
    params.pruneRelative = static_cast<float>(prune);
    params.pruneAbsolute = static_cast<float>(prune * scale2);
    return params;
  }

  /// The warm start of the first block: the host's guess on its first frame (a warm start
  /// only; later blocks start from the previous block's last hits).
  void seedOnce(DeviceArray& poses, DeviceArray& points) {
    if (mSeeded) {
      return;
    }
    std::vector<std::int32_t> seeds;
    correction::seedTriangles(mBvh, mSearch.triangles().data(), poses.read<float>(),
                              points.read<float>(), seeds);
    std::vector<SurfaceHit> seedHits(seeds.size());
    for (std::size_t i = 0; i < seeds.size(); ++i) {
      seedHits[i].triangle = seeds[i];
    }
    cl_util::guard("uploading the closest-triangle warm start", [&] {
      cl_util::upload(mQueue, mTransfers, mSeeds, CL_TRUE, 0, seedHits.size() * sizeof(SurfaceHit),
                      seedHits.data());
    });
    mSeeded = true;
  }

  /// Every node's box on every frame of `poses` (dsBvhRefit, one launch per depth) into mBoxes;
  /// kept while the poses keep their version (the resolution, its exit fade and the audit's
  /// recount read the boxes of one block).
  cl::Buffer& refitBoxes(int frameCount, DeviceArray& poses) {
    const cl::Buffer& posesBuffer = cl_util::readBuffer(poses);
    const int nodeCount = static_cast<int>(mBvh.nodes.size());
    const std::size_t boxBytes = static_cast<std::size_t>(frameCount) *
                                 static_cast<std::size_t>(nodeCount) * 6 * sizeof(float);
    cl::Buffer& boxBuffer = mBoxes.reserve(mContext, boxBytes);
    if (mBoxesOf == Refit{poses.version(), frameCount}) {
      return boxBuffer;
    }
    mBoxesOf = Refit{poses.version(), frameCount};
    DsBvhRefitParams refit{};
    refit.frameCount = frameCount;
    refit.vertexCount = mSearch.vertexCount();
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
    return boxBuffer;
  }

  /// Every node's cone on every frame of `poses` (dsCertRefitCones after the boxes, one launch
  /// per depth) into mCones; kept, as the boxes, while the poses keep their version.
  cl::Buffer& refitCones(int frameCount, DeviceArray& poses, const cl::Buffer& boxBuffer,
                         DsCertParams params) {
    cl::Buffer& coneBuffer = mCones.reserve(
        mContext, static_cast<std::size_t>(frameCount) * params.nodeCount * sizeof(DsCertCone));
    if (mConesOf == Refit{poses.version(), frameCount}) {
      return coneBuffer;
    }
    mConesOf = Refit{poses.version(), frameCount};
    const cl::Buffer& posesBuffer = cl_util::readBuffer(poses);
    // Arguments 0-4 stay; the level's range (in argument 5) changes per launch.
    cl_util::setArgs(mConeKernel, posesBuffer, mNodes, mLeafTriangles, boxBuffer, coneBuffer,
                     params);
    for (int level = mBvh.depth() - 1; level >= 0; --level) {
      params.levelFirst = mBvh.levelStart[static_cast<std::size_t>(level)];
      params.levelCount = mBvh.levelStart[static_cast<std::size_t>(level) + 1] - params.levelFirst;
      mConeKernel.setArg(5, params);
      cl_util::enqueue1d(mQueue, mConeKernel,
                         static_cast<std::size_t>(frameCount) * params.levelCount, DS_LOCAL_SIZE);
    }
    return coneBuffer;
  }

  /// ClosestBackend::closest through the BVH (see src/database/bvh.cpp and kernels/bvh.cl)
  /// on arrays of this context; `hits` sized F x Vd.
  void closestBvh(int frameCount, DeviceArray& poses, DeviceArray& points, DeviceArray& hits) {
    const int pointCount = mSearch.pointCount();
    if (frameCount == 0 || pointCount == 0) {
      return;
    }
    const std::size_t items = static_cast<std::size_t>(frameCount) * pointCount;
    const DsBvhQueryParams params = queryParams(frameCount);
    seedOnce(poses, points);
    cl_util::guard("running the closest-triangle kernels", [&] {
      const cl::Buffer& posesBuffer = cl_util::readBuffer(poses);
      const cl::Buffer& pointsBuffer = cl_util::readBuffer(points);
      cl::Buffer& hitBuffer = cl_util::writeBuffer(hits);
      cl::Buffer& boxBuffer = refitBoxes(frameCount, poses);
      cl_util::setArgs(mBvhKernel, posesBuffer, mTriangles, mNodes, mLeafTriangles, boxBuffer,
                       pointsBuffer, mPointRoot, mSeeds, hitBuffer, params);
      cl_util::enqueue1d(mQueue, mBvhKernel, items, DS_LOCAL_SIZE);
      // The next block starts from this block's last frame, copied on the device.
      mQueue.enqueueCopyBuffer(hitBuffer, mSeeds, (items - pointCount) * sizeof(SurfaceHit), 0,
                               static_cast<std::size_t>(pointCount) * sizeof(SurfaceHit));
    });
  }

  /// closestOrClearBlock on arrays of this context (src/devices/certificate.cpp): the
  /// boxes and cones of every frame, the check of every point, then one BVH search over the
  /// points left. `answered` (F x Vd, or null: scratch) as for closestOrClearBlock; cleared F.
  void clearOrSearch(int frameCount, DeviceArray& poses, DeviceArray& points, float clearance,
                     DeviceArray& hits, DeviceArray* answered, bool keep, int* cleared) {
    const int pointCount = mSearch.pointCount();
    const std::size_t items = static_cast<std::size_t>(frameCount) * pointCount;
    const DsBvhQueryParams query = queryParams(frameCount);
    seedOnce(poses, points);
    DsCertParams params{};
    params.frameCount = frameCount;
    params.pointCount = pointCount;
    params.vertexCount = mSearch.vertexCount();
    params.nodeCount = query.nodeCount;
    params.keep = keep ? 1 : 0;
    params.clearance = clearance;
    params.margin = static_cast<float>((mDouble ? DS_CERT_MARGIN_DOUBLE : DS_CERT_MARGIN_SINGLE) *
                                       mSearch.sceneScale());
    int searchCount = 0;
    cl_util::guard("running the clearance certificate", [&] {
      const cl::Buffer& posesBuffer = cl_util::readBuffer(poses);
      const cl::Buffer& pointsBuffer = cl_util::readBuffer(points);
      cl::Buffer& hitBuffer = keep ? cl_util::modifyBuffer(hits) : cl_util::writeBuffer(hits);
      cl::Buffer& answeredBuffer =
          answered == nullptr
              ? mAnswered.reserve(mContext, items * sizeof(cl_int))
              : (keep ? cl_util::modifyBuffer(*answered) : cl_util::writeBuffer(*answered));
      cl::Buffer& boxBuffer = refitBoxes(frameCount, poses);
      cl::Buffer& coneBuffer = refitCones(frameCount, poses, boxBuffer, params);
      const std::size_t countBytes = static_cast<std::size_t>(frameCount) * sizeof(cl_int);
      cl::Buffer& clearedBuffer = mCounts.reserve(mContext, countBytes);
      cl::Buffer& searchBuffer = mSearchList.reserve(mContext, items * sizeof(cl_int));
      cl::Buffer& searchCountBuffer = mSearchCount.reserve(mContext, sizeof(cl_int));
      mQueue.enqueueFillBuffer(clearedBuffer, cl_int(0), 0, countBytes);
      mQueue.enqueueFillBuffer(searchCountBuffer, cl_int(0), 0, sizeof(cl_int));
      cl_util::setArgs(mCertCheckKernel, posesBuffer, mTriangles, mNodes, mLeafTriangles,
                       mNodeTriangle, boxBuffer, coneBuffer, pointsBuffer, mSeeds, hitBuffer,
                       answeredBuffer, clearedBuffer, searchBuffer, searchCountBuffer, params);
      cl_util::enqueue1d(mQueue, mCertCheckKernel, items, DS_LOCAL_SIZE);
      cl_util::download(mQueue, mTransfers, searchCountBuffer, CL_TRUE, 0, sizeof(cl_int),
                        &searchCount);
      if (searchCount > 0) {
        cl_util::setArgs(mBvhListKernel, posesBuffer, mTriangles, mNodes, mLeafTriangles, boxBuffer,
                         pointsBuffer, mPointRoot, mSeeds, hitBuffer, query, searchBuffer,
                         cl_int(searchCount));
        cl_util::enqueue1d(mQueue, mBvhListKernel, static_cast<std::size_t>(searchCount),
                           DS_LOCAL_SIZE);
      }
      // The next block starts from this block's last frame (a witness is a fine seed too).
      mQueue.enqueueCopyBuffer(hitBuffer, mSeeds, (items - pointCount) * sizeof(SurfaceHit), 0,
                               static_cast<std::size_t>(pointCount) * sizeof(SurfaceHit));
      cl_util::download(mQueue, mTransfers, clearedBuffer, CL_TRUE, 0, countBytes, cleared);
    });
  }

  void transferOnDevice(int frameCount, DeviceArray& hits, DeviceArray& fromPoses,
                        DeviceArray& toPoses, DeviceArray& points, DeviceArray& out) {
    if (frameCount == 0 || mSearch.pointCount() == 0) {
      return;
    }
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    const DsTransferParams params = transferParams(frameCount);
    cl_util::guard("running the transfer kernel", [&] {
      const cl::Buffer& hitBuffer = cl_util::readBuffer(hits);
      const cl::Buffer& fromBuffer = cl_util::readBuffer(fromPoses);
      const cl::Buffer& toBuffer = cl_util::readBuffer(toPoses);
      const cl::Buffer& pointsBuffer = cl_util::readBuffer(points);
      cl::Buffer& outBuffer = cl_util::writeBuffer(out);
      cl_util::setArgs(mTransferKernel, hitBuffer, fromBuffer, toBuffer, mTriangles, pointsBuffer,
                       outBuffer, params);
      cl_util::enqueue1d(mQueue, mTransferKernel, items, DS_LOCAL_SIZE);
    });
  }

  void rebuildOnDevice(int frameCount, DeviceArray& hits, DeviceArray& toPoses, DeviceArray& local,
                       DeviceArray& out) {
    if (frameCount == 0 || mSearch.pointCount() == 0) {
      return;
    }
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    const DsTransferParams params = transferParams(frameCount);
    cl_util::guard("running the rebuild kernel", [&] {
      const cl::Buffer& hitBuffer = cl_util::readBuffer(hits);
      const cl::Buffer& toBuffer = cl_util::readBuffer(toPoses);
      const cl::Buffer& localBuffer = cl_util::readBuffer(local);
      cl::Buffer& outBuffer = cl_util::writeBuffer(out);
      cl_util::setArgs(mRebuildKernel, hitBuffer, toBuffer, mTriangles, localBuffer, outBuffer,
                       params);
      cl_util::enqueue1d(mQueue, mRebuildKernel, items, DS_LOCAL_SIZE);
    });
  }

  void resolveOnDevice(int frameCount, DeviceArray& poses, DeviceArray& hits, float offset,
                       DeviceArray& points, int* moved) {
    if (frameCount == 0) {
      return;
    }
    std::vector<int> counts(static_cast<std::size_t>(frameCount), 0);
    if (mSearch.pointCount() > 0) {
      cl_util::guard("refitting the BVH for the exit fade", [&] {
        // The boxes are read only with the fade on; any buffer stands in for them otherwise.
        const cl::Buffer& boxes = mFade > 0.0f ? refitBoxes(frameCount, poses) : mNodes;
        mResolveKernel.setArg(11, mNodes);
        mResolveKernel.setArg(12, mLeafTriangles);
        mResolveKernel.setArg(13, boxes);
        mResolveKernel.setArg(14, mPointRoot);
      });
      launchSigned(mResolveKernel, frameCount, poses, hits, cl_util::modifyBuffer(points), offset,
                   mFade, counts.data(), "running the penetration-resolution kernel");
    }
    if (moved != nullptr) {
      std::copy(counts.begin(), counts.end(), moved);
    }
  }

  /// Runs dsResolve or dsCountInside (same first arguments, the side table included; dsResolve's
  /// BVH arguments are set by the caller) over every point of `frameCount` frames and reads back
  /// their per-frame counters into `counts`.
  void launchSigned(cl::Kernel& kernel, int frameCount, DeviceArray& poses, DeviceArray& hits,
                    const cl::Buffer& pointsBuffer, float offset, float fade, int* counts,
                    const char* what) {
    const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
    const std::size_t countBytes = static_cast<std::size_t>(frameCount) * sizeof(cl_int);
    DsResolveParams params{};
    params.frameCount = frameCount;
    params.pointCount = mSearch.pointCount();
    params.vertexCount = mSearch.vertexCount();
    params.triangleCount = mSearch.triangleCount();
    params.offset = offset;
    params.sided = mSided ? 1 : 0;
    params.fade = fade;
    params.nodeCount = static_cast<cl_int>(mBvh.nodes.size());
    cl_util::guard(what, [&] {
      const cl::Buffer& posesBuffer = cl_util::readBuffer(poses);
      const cl::Buffer& hitBuffer = cl_util::readBuffer(hits);
      cl::Buffer& countBuffer = mCounts.reserve(mContext, countBytes);
      mQueue.enqueueFillBuffer(countBuffer, cl_int(0), 0, countBytes);
      cl_util::setArgs(kernel, posesBuffer, mTriangles, mEdgeStart, mEdgeTriangles, mVertexStart,
                       mVertexTriangles, hitBuffer, pointsBuffer, countBuffer, mSides, params);
      cl_util::enqueue1d(mQueue, kernel, items, DS_LOCAL_SIZE);
      static_assert(sizeof(cl_int) == sizeof(int), "counts are read as int");
      cl_util::download(mQueue, mTransfers, countBuffer, CL_TRUE, 0, countBytes, counts);
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
  cl::Kernel mCountInsideKernel;
  cl::Kernel mRefitKernel;
  cl::Kernel mBvhKernel;
  cl::Kernel mBvhListKernel;
  cl::Kernel mConeKernel;
  cl::Kernel mCertCheckKernel;
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
  bool mSeeded = false;
  cl::Buffer mSides;  ///< Vd chars (ClosestBackend::setSides), or a placeholder when !mSided
  bool mSided = false;
  float mFade = 0.0f;  ///< setExitFade()
  bool mCertifiable = false;
  cl::Buffer mNodeTriangle;
  /// Which poses the boxes and cones were refitted on: DeviceArray::version() and the frames.
  struct Refit {
    std::uint64_t version = 0;
    int frames = 0;
    bool operator==(const Refit& other) const {
      return version == other.version && frames == other.frames;
    }
  };
  Refit mBoxesOf;
  Refit mConesOf;
  cl_util::GrowingBuffer mCones{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mSearchList{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mAnswered{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mSearchCount{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mBoxes{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mPoses{CL_MEM_READ_ONLY};  // the candidate path's
  cl_util::GrowingBuffer mPoints{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mStart{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mCandidateTriangles{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mHits{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mCounts{CL_MEM_READ_WRITE};
  // Views of the raw calls' memory (and of arrays of other devices) for the array path.
  DeviceArray mViewPoses, mViewToPoses, mViewPoints, mViewHits, mViewOut, mViewAnswered;
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
