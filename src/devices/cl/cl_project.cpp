// SPDX-License-Identifier: Apache-2.0
// The launches of kernels/project.cl: ClStages::project and projectBlock (cl_stages.h; the
// backend's glue is cl_stages.cpp).

#include "cl_stages.h"

#include <algorithm>
#include <cstddef>
#include <vector>

#include <drivenshape/error.h>
#include <shared_types.h>

#include "cl_program.h"
#include "stage_checks.h"

namespace drivenshape {

void ClStages::project(int frameCount, const float* driverFrames, float* projections,
                       float* norms) {
  checkProject(frameCount, driverFrames != nullptr, projections, norms);
  if (frameCount == 0) {
    return;
  }
  const std::size_t frames = static_cast<std::size_t>(frameCount);
  reserveFrames(frames);
  cl_util::guard("uploading a chunk of driver frames", [&] {
    writeRows(mFrames.buffer, driverFrames, frames, mDriverCount, mDriverPadded);
  });
  projectFrames(frameCount, projections, norms);
}

void ClStages::projectBlock(int frameCount, DeviceArray& driverFrames, float* projections,
                            float* norms) {
  if (!cl_util::onContext(mContext, driverFrames)) {
    StageBackend::projectBlock(frameCount, driverFrames, projections, norms);
    return;
  }
  checkProject(frameCount, true, projections, norms);
  if (frameCount == 0) {
    return;
  }
  const std::size_t frames = static_cast<std::size_t>(frameCount);
  reserveFrames(frames);
  cl_util::guard("copying a block of driver frames on the device", [&] {
    copyRows(cl_util::readBuffer(driverFrames), mDriverCount, mFrames.buffer, mDriverPadded, frames,
             mDriverCount);
  });
  projectFrames(frameCount, projections, norms);
}

void ClStages::checkProject(int frameCount, bool framesPresent, const float* projections,
                            const float* norms) const {
  stage_checks::checkCall("project", mUploaded, frameCount);
  if (mBlendOnly) {
    DS_THROW(kInternal, "StageBackend::project needs the driver tables; these are blend-only");
  }
  if (frameCount > 0 &&
      (!framesPresent || norms == nullptr || (mRowCount > 0 && projections == nullptr))) {
    DS_THROW(kInternal, "StageBackend::project called with a null buffer");
  }
}

void ClStages::reserveFrames(std::size_t frames) {
  reserve(mFrames, frames * mDriverPadded * sizeof(float), CL_MEM_READ_ONLY, true,
          "allocating the driver frame buffer");
}

/// dsProject on the frames in mFrames, then one read back of projections and norms.
void ClStages::projectFrames(int frameCount, float* projections, float* norms) {
  const std::size_t frames = static_cast<std::size_t>(frameCount);
  const std::size_t outStride = static_cast<std::size_t>(mRowCount) + 2;
  reserve(mProjected, frames * outStride * sizeof(float), CL_MEM_WRITE_ONLY, false,
          "allocating the projection buffer");
  DsProjectParams params{};
  params.quadCount = static_cast<int>(mDriverPadded / 4);
  params.rowCount = mRowCount;
  params.tileCount = mTileCount;
  params.frameCount = frameCount;
  params.outStride = static_cast<int>(outStride);
  cl_util::guard("running dsProject on a chunk of frames", [&] {
    mProject.setArg(0, mFrames.buffer);
    mProject.setArg(1, mCenter);
    mProject.setArg(2, mRows);
    mProject.setArg(3, mProjected.buffer);
    mProject.setArg(4, params);
    const std::size_t groups = frames * static_cast<std::size_t>(mTileCount);
    mQueue.enqueueNDRangeKernel(mProject, cl::NullRange, cl::NDRange(groups * DS_LOCAL_SIZE),
                                cl::NDRange(DS_LOCAL_SIZE));
  });

  mStaging.resize(frames * outStride);
  cl_util::guard("reading back the projections", [&] {
    cl_util::download(mQueue, mTransfers, mProjected.buffer, CL_TRUE, 0,
                      mStaging.size() * sizeof(float), mStaging.data());
  });
  const std::size_t rows = static_cast<std::size_t>(mRowCount);
  for (std::size_t f = 0; f < frames; ++f) {
    const float* in = mStaging.data() + f * outStride;
    std::copy(in, in + rows, projections + f * rows);
    norms[2 * f] = in[rows];
    norms[2 * f + 1] = in[rows + 1];
  }
}

}  // namespace drivenshape
