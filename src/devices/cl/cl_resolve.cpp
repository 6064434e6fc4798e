// SPDX-License-Identifier: Apache-2.0
// The launches of kernels/resolve.cl (cl_closest.h; the backend's glue is cl_closest.cpp):
// the penetration resolution, the strain limit's skin planes and the inside count.

#include "cl_closest.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace drivenshape {

void ClClosest::resolve(int frameCount, const float* poses, const SurfaceHit* hits, float offset,
                        float* points, int* moved) {
  correction::checkResolve(mSearch, frameCount, poses, hits, offset, points);
  const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
  mViewPoses.view(poses, static_cast<std::size_t>(frameCount) * poseValues());
  mViewHits.view(hits, items);
  mViewOut.view(points, items * 3);
  resolveOnDevice(frameCount, mViewPoses, mViewHits, offset, mViewOut, moved);
  mViewOut.read<float>();
}

void ClClosest::resolveBlock(int frameCount, DeviceArray& poses, DeviceArray& hits, float offset,
                             DeviceArray& points, int* moved) {
  mSearch.checkChunk("penetration resolution", frameCount, true);
  const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
  correction::checkOffset(offset);
  checkInputs("penetration resolution", frameCount, &poses, &points, &hits, items);
  DeviceArray& result = outputOnDevice(points, mViewOut, items * 3 * sizeof(float), true);
  resolveOnDevice(frameCount, onDevice(poses, mViewPoses), onDevice(hits, mViewHits), offset,
                  result, moved);
  finishOutput(result, mViewOut);
}

void ClClosest::skinPlanes(int frameCount, const float* poses, const SurfaceHit* hits,
                           const std::int32_t* answered, const float* points, float offset,
                           float depth, float reach, float* planes) {
  correction::checkResolve(mSearch, frameCount, poses, hits, offset, points);
  const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
  mViewPoses.view(poses, static_cast<std::size_t>(frameCount) * poseValues());
  mViewHits.view(hits, items);
  mViewPoints.view(points, items * 3);
  if (answered != nullptr) {
    mViewAnswered.view(answered, items);
  }
  mViewOut.view(planes, items * 4);
  correction::checkOffset(depth);
  correction::checkOffset(reach);
  skinPlanesOnDevice(frameCount, mViewPoses, mViewHits,
                     answered != nullptr ? &mViewAnswered : nullptr, mViewPoints, offset, depth,
                     reach, mViewOut);
  mViewOut.read<float>();
}

void ClClosest::skinPlanesBlock(int frameCount, DeviceArray& poses, DeviceArray& hits,
                                DeviceArray* answered, DeviceArray& points, float offset,
                                float depth, float reach, DeviceArray& planes) {
  mSearch.checkChunk("skin planes", frameCount, true);
  const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
  correction::checkOffset(offset);
  correction::checkOffset(depth);
  correction::checkOffset(reach);
  checkInputs("skin planes", frameCount, &poses, &points, &hits, items);
  DeviceArray& out = outputOnDevice(planes, mViewOut, items * 4 * sizeof(float), false);
  skinPlanesOnDevice(frameCount, onDevice(poses, mViewPoses), onDevice(hits, mViewHits),
                     answered != nullptr ? &onDevice(*answered, mViewAnswered) : nullptr,
                     onDevice(points, mViewPoints), offset, depth, reach, out);
  finishOutput(out, mViewOut);
}

void ClClosest::skinPlanesOnDevice(int frameCount, DeviceArray& poses, DeviceArray& hits,
                                   DeviceArray* answered, DeviceArray& points, float offset,
                                   float depth, float reach, DeviceArray& planes) {
  const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
  if (items == 0) {
    return;
  }
  DsResolveParams params = signedParams(frameCount, offset);
  params.depth = depth;
  params.answered = answered != nullptr ? 1 : 0;
  params.reach = reach;
  cl_util::guard("running the skin-plane kernel", [&] {
    const cl::Buffer& posesBuffer = cl_util::readBuffer(poses);
    const cl::Buffer& hitBuffer = cl_util::readBuffer(hits);
    const cl::Buffer& pointBuffer = cl_util::readBuffer(points);
    // Without marks any buffer stands in for them: the kernel does not read it.
    const cl::Buffer& answeredBuffer =
        answered != nullptr ? cl_util::readBuffer(*answered) : mTriangles;
    cl_util::setArgs(mSkinPlanesKernel, posesBuffer, mTriangles, mEdgeStart, mEdgeTriangles,
                     mVertexStart, mVertexTriangles, hitBuffer, pointBuffer, answeredBuffer, mSides,
                     cl_util::writeBuffer(planes), params);
    cl_util::enqueue1d(mQueue, mSkinPlanesKernel, items, DS_LOCAL_SIZE);
  });
}

void ClClosest::countInside(int frameCount, DeviceArray& poses, DeviceArray& hits,
                            DeviceArray& points, int* inside) {
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
  launchSigned(mCountInsideKernel, frameCount, posesOn, hitsOn, cl_util::readBuffer(pointsOn), 0.0f,
               0.0f, inside, "running the inside-count kernel");
}

void ClClosest::resolveOnDevice(int frameCount, DeviceArray& poses, DeviceArray& hits, float offset,
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

DsResolveParams ClClosest::signedParams(int frameCount, float offset) const {
  DsResolveParams params{};
  params.frameCount = frameCount;
  params.pointCount = mSearch.pointCount();
  params.vertexCount = mSearch.vertexCount();
  params.triangleCount = mSearch.triangleCount();
  params.offset = offset;
  params.sided = mSided ? 1 : 0;
  params.alongNormal = mAlongNormal ? 1 : 0;
  return params;
}

/// Runs dsResolve or dsCountInside (same first arguments, the side table included; dsResolve's
/// BVH arguments are set by the caller) over every point of `frameCount` frames and reads back
/// their per-frame counters into `counts`.
void ClClosest::launchSigned(cl::Kernel& kernel, int frameCount, DeviceArray& poses,
                             DeviceArray& hits, const cl::Buffer& pointsBuffer, float offset,
                             float fade, int* counts, const char* what) {
  const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
  const std::size_t countBytes = static_cast<std::size_t>(frameCount) * sizeof(cl_int);
  DsResolveParams params = signedParams(frameCount, offset);
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

}  // namespace drivenshape
