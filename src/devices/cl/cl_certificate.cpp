// SPDX-License-Identifier: Apache-2.0
// The launches of kernels/certificate.cl (cl_closest.h; the backend's glue is cl_closest.cpp):
// closestOrClearBlock, the clearance certificate (the scheme: src/devices/certificate.cpp) with
// the BVH search (cl_bvh.cpp) of the points it does not clear.

#include "cl_closest.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace drivenshape {

void ClClosest::closestOrClearBlock(int frameCount, DeviceArray& poses, DeviceArray& points,
                                    float clearance, DeviceArray& hits, int* cleared,
                                    DeviceArray* answered, bool keep, float reach) {
  if (!mUseBvh || !mCertifiable) {
    ClosestBackend::closestOrClearBlock(frameCount, poses, points, clearance, hits, cleared,
                                        answered, keep, reach);
    return;
  }
  mSearch.checkChunk("closest triangle", frameCount, true);
  correction::checkOffset(clearance);
  correction::checkOffset(reach);
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
    clearOrSearch(frameCount, onDevice(poses, mViewPoses), onDevice(points, mViewPoints), clearance,
                  reach, out, marks, kept, counts.data());
    finishOutput(out, mViewHits);
    if (marks != nullptr) {
      finishOutput(*marks, mViewAnswered);
    }
  }
  if (cleared != nullptr) {
    std::copy(counts.begin(), counts.end(), cleared);
  }
}

/// Every node's cone on every frame of `poses` (dsCertRefitCones after the boxes, one launch
/// per depth) into mCones; kept, as the boxes, while the poses keep their version.
cl::Buffer& ClClosest::refitCones(int frameCount, DeviceArray& poses, const cl::Buffer& boxBuffer,
                                  DsCertParams params) {
  cl::Buffer& coneBuffer = mCones.reserve(
      mContext, static_cast<std::size_t>(frameCount) * params.nodeCount * sizeof(DsCertCone));
  if (mConesOf == Refit{poses.version(), frameCount}) {
    return coneBuffer;
  }
  mConesOf = Refit{poses.version(), frameCount};
  const cl::Buffer& posesBuffer = cl_util::readBuffer(poses);
  // Arguments 0-4 stay; the level's range (in argument 5) changes per launch.
  cl_util::setArgs(mConeKernel, posesBuffer, mNodes, mLeafTriangles, boxBuffer, coneBuffer, params);
  for (int level = mBvh.depth() - 1; level >= 0; --level) {
    params.levelFirst = mBvh.levelStart[static_cast<std::size_t>(level)];
    params.levelCount = mBvh.levelStart[static_cast<std::size_t>(level) + 1] - params.levelFirst;
    mConeKernel.setArg(5, params);
    cl_util::enqueue1d(mQueue, mConeKernel,
                       static_cast<std::size_t>(frameCount) * params.levelCount, DS_LOCAL_SIZE);
  }
  return coneBuffer;
}

/// closestOrClearBlock on arrays of this context (src/devices/certificate.cpp): the
/// boxes and cones of every frame, the check of every point, then one BVH search over the
/// points left. `answered` (F x Vd, or null: scratch) as for closestOrClearBlock; cleared F.
void ClClosest::clearOrSearch(int frameCount, DeviceArray& poses, DeviceArray& points,
                              float clearance, float reach, DeviceArray& hits,
                              DeviceArray* answered, bool keep, int* cleared) {
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
  params.reach = reach;
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
    mQueue.enqueueFillBuffer(searchCountBuffer, cl_int(0), 0, sizeof(cl_int));
    cl_util::setArgs(mCertCheckKernel, posesBuffer, mTriangles, mNodes, mLeafTriangles,
                     mNodeTriangle, boxBuffer, coneBuffer, pointsBuffer, mSeeds, hitBuffer,
                     answeredBuffer, searchBuffer, searchCountBuffer, params);
    cl_util::enqueue1d(mQueue, mCertCheckKernel, items, DS_LOCAL_SIZE);
    cl_util::setArgs(mCertCountKernel, answeredBuffer, clearedBuffer, cl_int(pointCount));
    mQueue.enqueueNDRangeKernel(mCertCountKernel, cl::NullRange,
                                cl::NDRange(DS_LOCAL_SIZE, static_cast<std::size_t>(frameCount)),
                                cl::NDRange(DS_LOCAL_SIZE, 1));
    cl_util::download(mQueue, mTransfers, searchCountBuffer, CL_TRUE, 0, sizeof(cl_int),
                      &searchCount);
    if (searchCount > 0) {
      cl_util::setArgs(mBvhListKernel, posesBuffer, mTriangles, mNodes, mLeafTriangles, boxBuffer,
                       pointsBuffer, mPointRoot, hitBuffer, query, searchBuffer,
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

}  // namespace drivenshape
