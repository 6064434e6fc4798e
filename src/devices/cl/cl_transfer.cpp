// SPDX-License-Identifier: Apache-2.0
// The launches of kernels/transfer.cl (cl_closest.h; the backend's glue is cl_closest.cpp):
// the local-frame transfer and rebuild, on raw memory and on arrays.

#include "cl_closest.h"

#include <algorithm>
#include <cstddef>

namespace drivenshape {

void ClClosest::transfer(int frameCount, const SurfaceHit* hits, const float* fromPoses,
                         const float* toPoses, const float* points, float* out) {
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

void ClClosest::rebuild(int frameCount, const SurfaceHit* hits, const float* toPoses,
                        const float* local, float* out) {
  correction::checkRebuild(mSearch, frameCount, hits, toPoses, local, out);
  const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
  mViewHits.view(hits, static_cast<std::size_t>(mSearch.pointCount()));
  mViewToPoses.view(toPoses, static_cast<std::size_t>(frameCount) * poseValues());
  mViewPoints.view(local, items * 3);
  mViewOut.view(out, items * 3);
  rebuildOnDevice(frameCount, mViewHits, mViewToPoses, mViewPoints, mViewOut);
  mViewOut.read<float>();
}

void ClClosest::transferBlock(int frameCount, DeviceArray& hits, DeviceArray& fromPoses,
                              DeviceArray& toPoses, DeviceArray& points, DeviceArray& out) {
  mSearch.checkChunk("transfer", frameCount, true);
  const std::size_t items = static_cast<std::size_t>(frameCount) * mSearch.pointCount();
  checkInputs("transfer", frameCount, &fromPoses, &points, &hits, items);
  checkInputs("transfer", frameCount, &toPoses, nullptr, nullptr, 0);
  DeviceArray& result = outputOnDevice(out, mViewOut, items * 3 * sizeof(float), false);
  transferOnDevice(frameCount, onDevice(hits, mViewHits), onDevice(fromPoses, mViewPoses),
                   onDevice(toPoses, mViewToPoses), onDevice(points, mViewPoints), result);
  finishOutput(result, mViewOut);
}

void ClClosest::rebuildBlock(int frameCount, DeviceArray& hits, DeviceArray& toPoses,
                             DeviceArray& local, DeviceArray& out) {
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

/// The sizes the transfer and rebuild kernels share.
DsTransferParams ClClosest::transferParams(int frameCount) const {
  DsTransferParams params{};
  params.frameCount = frameCount;
  params.pointCount = mSearch.pointCount();
  params.vertexCount = mSearch.vertexCount();
  params.triangleCount = mSearch.triangleCount();
  return params;
}

void ClClosest::transferOnDevice(int frameCount, DeviceArray& hits, DeviceArray& fromPoses,
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

void ClClosest::rebuildOnDevice(int frameCount, DeviceArray& hits, DeviceArray& toPoses,
                                DeviceArray& local, DeviceArray& out) {
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

}  // namespace drivenshape
