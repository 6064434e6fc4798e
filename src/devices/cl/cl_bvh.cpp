// SPDX-License-Identifier: Apache-2.0
// The launches of kernels/bvh.cl (cl_closest.h; the backend's glue is cl_closest.cpp): the
// per-frame refit of the boxes and the exact closest triangle by a walk of the refitted BVH
// from a warm start (src/database/bvh.cpp).

#include "cl_closest.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace drivenshape {

/// The BVH query's scalars for a chunk of `frameCount` frames.
DsBvhQueryParams ClClosest::queryParams(int frameCount) const {
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
void ClClosest::seedOnce(DeviceArray& poses, DeviceArray& points) {
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
cl::Buffer& ClClosest::refitBoxes(int frameCount, DeviceArray& poses) {
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

/// ClosestBackend::closest through the BVH (see src/database/bvh.cpp and kernels/bvh.cl)
/// on arrays of this context; `hits` sized F x Vd.
void ClClosest::closestBvh(int frameCount, DeviceArray& poses, DeviceArray& points,
                           DeviceArray& hits) {
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

}  // namespace drivenshape
