// SPDX-License-Identifier: Apache-2.0
// The glue of the OpenCL correction backend (cl_closest.h): the program build, setSurface and
// the array helpers every launch shares, and the launches of kernels/closest.cl (the exact
// choice from the host candidate lists, ClosestOptions::kCandidates). ClosestBackend::closest
// and closestBlock start here and walk the BVH by default (cl_bvh.cpp).

#include "cl_closest.h"

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

#include "certificate.h"
#include "cl_backends.h"
#include "surface_features.h"

namespace drivenshape {
namespace cl_closest {

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

}  // namespace cl_closest

ClClosest::ClClosest(const cl_util::ClTarget& target, const ClosestOptions& options)
    : mContext(target.context),
      mDevice(target.device),
      mQueue(target.queue),
      mTransfers(target.transfers),
      mUseBvh(options.deviceSearch == ClosestOptions::DeviceSearch::kBvh),
      mSearch(options.threads),
      mViewPoses(cl_closest::storage(target)),
      mViewToPoses(cl_closest::storage(target)),
      mViewPoints(cl_closest::storage(target)),
      mViewHits(cl_closest::storage(target)),
      mViewOut(cl_closest::storage(target)),
      mViewAnswered(cl_closest::storage(target)) {
  mDouble = !options.forceSinglePrecision && cl_closest::hasFp64(mDevice);
  std::vector<std::string> defines;
  if (mDouble) {
    defines.push_back("DS_USE_DOUBLE");
  }
  mProgram =
      cl_util::buildProgram(target,
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
    mSkinPlanesKernel = cl::Kernel(mProgram, "dsSkinPlanes");
    mRefitKernel = cl::Kernel(mProgram, "dsBvhRefit");
    mBvhKernel = cl::Kernel(mProgram, "dsBvhClosest");
    mBvhListKernel = cl::Kernel(mProgram, "dsBvhClosestList");
    mConeKernel = cl::Kernel(mProgram, "dsCertRefitCones");
    mCertCheckKernel = cl::Kernel(mProgram, "dsCertCheck");
    mCertCountKernel = cl::Kernel(mProgram, "dsCertCount");
    mName = mDevice.getInfo<CL_DEVICE_NAME>();
  });
}

void ClClosest::setSurface(const Mesh& driver, const BindingMask& mask) {
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

void ClClosest::setExitFade(float fade) {
  correction::checkExitFade(fade);
  mFade = fade;
}

void ClClosest::setSides(const std::vector<std::int8_t>& sides) {
  correction::checkSides(sides, mSearch.pointCount());
  cl_util::guard("uploading the side table", [&] {
    mSides = uploadBytes(sides.data(), sides.size());
    mSided = !sides.empty();
  });
}

void ClClosest::closest(int frameCount, const float* poses, const float* points, SurfaceHit* hits) {
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

void ClClosest::closestBlock(int frameCount, DeviceArray& poses, DeviceArray& points,
                             DeviceArray& hits) {
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

/// `array` itself when its device side is on this context; else `view` over its host copy
/// (an array of another device, or of the host), uploaded by the kernel call that reads it.
DeviceArray& ClClosest::onDevice(DeviceArray& array, DeviceArray& view) {
  if (cl_util::onContext(mContext, array)) {
    return array;
  }
  view.view(array.read<unsigned char>(), array.bytes());
  return view;
}

/// An output array as the kernels see it: `target` itself when it is on this context, else
/// `view` over its host copy (`keep`: with its current values, for updates in place), which
/// finishOutput() brings back. The caller sizes `target` (at least `bytes`).
DeviceArray& ClClosest::outputOnDevice(DeviceArray& target, DeviceArray& view, std::size_t bytes,
                                       bool keep) {
  if (target.bytes() < bytes) {
    DS_THROW(kInternal, "an output block of ", target.bytes(), " bytes was given for ", bytes);
  }
  if (cl_util::onContext(mContext, target)) {
    return target;
  }
  view.view(keep ? target.modify<unsigned char>() : target.write<unsigned char>(), target.bytes());
  return view;
}

/// Downloads an output that went through a view into its target's host copy.
void ClClosest::finishOutput(DeviceArray& used, DeviceArray& view) {
  if (&used == &view) {
    view.read<unsigned char>();
  }
}

/// The raw calls' NaN and range checks on the host copies that are current (see
/// correction::checkFinite): poses F x 3Vp, points F x 3Vd, `hitCount` hits.
void ClClosest::checkInputs(const char* stage, int frameCount, DeviceArray* poses,
                            DeviceArray* points, DeviceArray* hits, std::size_t hitCount) const {
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

cl::Buffer ClClosest::uploadBytes(const void* data, std::size_t bytes) {
  cl::Buffer buffer(mContext, CL_MEM_READ_ONLY, std::max<std::size_t>(bytes, 16));
  if (bytes > 0) {
    cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, bytes, data);
  }
  return buffer;
}

/// A read-only device copy of a host table (at least one element, so empty tables work).
cl::Buffer ClClosest::upload(const std::vector<std::int32_t>& table) {
  const std::size_t bytes = std::max<std::size_t>(table.size(), 1) * sizeof(std::int32_t);
  cl::Buffer buffer(mContext, CL_MEM_READ_ONLY, bytes);
  if (!table.empty()) {
    cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, table.size() * sizeof(std::int32_t),
                    table.data());
  }
  return buffer;
}

/// ClosestBackend::closest with the host candidate lists (ClosestOptions::kCandidates).
void ClClosest::closestCandidates(int frameCount, const float* poses, const float* points,
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
    cl::Buffer& candidateBuffer =
        mCandidateTriangles.reserve(mContext, mCandidates.triangles.size() * sizeof(std::int32_t));
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
    cl_util::download(mQueue, mTransfers, hitBuffer, CL_TRUE, 0, items * sizeof(SurfaceHit), hits);
  });
}

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
