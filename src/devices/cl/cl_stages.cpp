// SPDX-License-Identifier: Apache-2.0
// The glue of the OpenCL per-frame stages (cl_stages.h): the program build, upload of the tables
// and the buffer helpers the launches share. The launches are one file per kernel stem:
// cl_project.cpp (kernels/project.cl) and cl_blend.cpp (kernels/blend.cl).

#include "cl_stages.h"

#include <algorithm>
#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape_kernels/blend_cl.h>
#include <drivenshape_kernels/project_cl.h>
#include <shared_types.h>

#include "cl_backends.h"
#include "cl_program.h"
#include "stage_checks.h"

namespace drivenshape {
namespace cl_stages {

// Copies `rows` rows of `count` floats into a zero-padded block of `padded` floats per row.
std::vector<float> padRows(const float* data, std::size_t rows, std::size_t count,
                           std::size_t padded) {
  std::vector<float> out(rows * padded, 0.0f);
  for (std::size_t r = 0; r < rows; ++r) {
    std::copy(data + r * count, data + (r + 1) * count, out.begin() + r * padded);
  }
  return out;
}

}  // namespace cl_stages

ClStages::ClStages(const cl_util::ClTarget& target)
    : mContext(target.context),
      mDevice(target.device),
      mQueue(target.queue),
      mTransfers(target.transfers) {
  mName =
      cl_util::guard("querying the device name", [&] { return mDevice.getInfo<CL_DEVICE_NAME>(); });
  mProgram = cl_util::buildProgram(target, {{kernels::kProjectSourceName, kernels::kProjectSource},
                                            {kernels::kBlendSourceName, kernels::kBlendSource}});
  cl_util::guard("creating the stage kernels", [&] {
    mProject = cl::Kernel(mProgram, "dsProject");
    mBlend = cl::Kernel(mProgram, "dsBlend");
  });
}

void ClStages::upload(const ShapeTables& tables) {
  stage_checks::checkTables(tables);
  mUploaded = false;
  // New tables may change the padded layout: the zeroed padding of the old chunk buffers
  // would sit in the wrong columns, so they are reallocated on the next call.
  mFrames = ChunkBuffer{};
  mProjected = ChunkBuffer{};
  mWeights = ChunkBuffer{};
  mDrivenOut = ChunkBuffer{};
  mDriverOut = ChunkBuffer{};
  mShapeCount = tables.shapeCount;
  mBlendOnly = tables.blendOnly();
  mRowCount = mBlendOnly ? 0 : tables.shapeCount - 1;
  mTileCount = std::max(1, (mRowCount + DS_PROJECT_ROWS - 1) / DS_PROJECT_ROWS);

  const std::size_t np = 3 * static_cast<std::size_t>(tables.driverVertexCount);
  const std::size_t nd = 3 * static_cast<std::size_t>(tables.drivenVertexCount);
  mDriverCount = np;
  mDriverPadded = cl_stages::paddedCount(np);

  if (mBlendOnly) {
    cl_util::guard("uploading the driven shapes",
                   [&] { mDriven = makeBlendTable(tables.drivenShapes, nd); });
    mUploaded = true;
    return;
  }
  // Projection rows, padded to whole tiles with zero rows (the kernel's row loop is fixed).
  std::vector<float> rows = cl_stages::padRows(
      tables.projectionRows.data(), static_cast<std::size_t>(mRowCount), np, mDriverPadded);
  rows.resize(static_cast<std::size_t>(mTileCount) * DS_PROJECT_ROWS * mDriverPadded, 0.0f);
  std::vector<float> center = cl_stages::padRows(tables.center.data(), 1, np, mDriverPadded);

  cl_util::guard("uploading the projection tables", [&] {
    mRows = cl_util::readOnlyBuffer(mContext, rows);
    mCenter = cl_util::readOnlyBuffer(mContext, center);
  });
  cl_util::guard("uploading the driven shapes",
                 [&] { mDriven = makeBlendTable(tables.drivenShapes, nd); });
  cl_util::guard("uploading the driver shapes",
                 [&] { mDriver = makeBlendTable(tables.driverShapes, np); });
  mUploaded = true;
}

ClStages::BlendTable ClStages::makeBlendTable(const std::vector<float>& shapes, std::size_t count) {
  const std::size_t k = static_cast<std::size_t>(mShapeCount);
  BlendTable table;
  table.count = count;
  table.padded = cl_stages::paddedCount(count);
  // Reference = mean shape (in double, rounded once); deltas = shape - reference, exact in
  // float wherever the two are within a factor of two (Sterbenz), i.e. almost everywhere.
  std::vector<float> reference(table.padded, 0.0f);
  std::vector<float> deltas(k * table.padded, 0.0f);
  for (std::size_t j = 0; j < count; ++j) {
    double mean = 0.0;
    for (std::size_t i = 0; i < k; ++i) {
      mean += static_cast<double>(shapes[i * count + j]);
    }
    const float ref = static_cast<float>(mean / static_cast<double>(k));
    reference[j] = ref;
    for (std::size_t i = 0; i < k; ++i) {
      deltas[i * table.padded + j] =
          static_cast<float>(static_cast<double>(shapes[i * count + j]) - static_cast<double>(ref));
    }
  }
  table.deltas = cl_util::readOnlyBuffer(mContext, deltas);
  table.reference = cl_util::readOnlyBuffer(mContext, reference);
  return table;
}

void ClStages::reserve(ChunkBuffer& chunk, std::size_t bytes, cl_mem_flags flags, bool zeroFill,
                       const char* what) {
  if (chunk.bytes >= bytes) {
    return;
  }
  cl_util::guard(what, [&] {
    chunk.buffer = cl::Buffer(mContext, flags, bytes);
    if (zeroFill) {
      // The padding columns of a padded block are never written afterwards.
      mQueue.enqueueFillBuffer(chunk.buffer, 0.0f, 0, bytes);
    }
  });
  chunk.bytes = bytes;
}

// Host block (rows x count, packed) -> device block (rows x padded). Blocking: the caller's
// memory may go away as soon as we return or throw.
void ClStages::writeRows(const cl::Buffer& buffer, const float* data, std::size_t rows,
                         std::size_t count, std::size_t padded) {
  if (count == padded) {
    cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, rows * count * sizeof(float), data);
    return;
  }
  const std::array<cl::size_type, 3> origin{0, 0, 0};
  const std::array<cl::size_type, 3> region{count * sizeof(float), rows, 1};
  mQueue.enqueueWriteBufferRect(buffer, CL_TRUE, origin, origin, region, padded * sizeof(float), 0,
                                count * sizeof(float), 0, data);
  cl_util::countTransfer(mTransfers, true, rows * count * sizeof(float));
}

// Device block (rows x padded) -> host block (rows x count, packed). Blocking.
void ClStages::readRows(const cl::Buffer& buffer, float* data, std::size_t rows, std::size_t count,
                        std::size_t padded) {
  if (count == padded) {
    cl_util::download(mQueue, mTransfers, buffer, CL_TRUE, 0, rows * count * sizeof(float), data);
    return;
  }
  const std::array<cl::size_type, 3> origin{0, 0, 0};
  const std::array<cl::size_type, 3> region{count * sizeof(float), rows, 1};
  mQueue.enqueueReadBufferRect(buffer, CL_TRUE, origin, origin, region, padded * sizeof(float), 0,
                               count * sizeof(float), 0, data);
  cl_util::countTransfer(mTransfers, false, rows * count * sizeof(float));
}

/// Device-to-device copy of `rows` rows of `count` floats between blocks with row pitches
/// `fromPitch` and `toPitch` (floats).
void ClStages::copyRows(const cl::Buffer& from, std::size_t fromPitch, const cl::Buffer& to,
                        std::size_t toPitch, std::size_t rows, std::size_t count) {
  if (fromPitch == count && toPitch == count) {
    mQueue.enqueueCopyBuffer(from, to, 0, 0, rows * count * sizeof(float));
    return;
  }
  const std::array<cl::size_type, 3> origin{0, 0, 0};
  const std::array<cl::size_type, 3> region{count * sizeof(float), rows, 1};
  mQueue.enqueueCopyBufferRect(from, to, origin, origin, region, fromPitch * sizeof(float), 0,
                               toPitch * sizeof(float), 0);
}

std::unique_ptr<StageBackend> makeClStages(const cl_util::ClTarget& target) {
  return std::make_unique<ClStages>(target);
}

std::unique_ptr<StageBackend> makeClStages(const cl::Context& context, const cl::Device& device,
                                           const cl::CommandQueue& queue) {
  return makeClStages(cl_util::ClTarget{context, device, queue});
}

}  // namespace drivenshape
