// SPDX-License-Identifier: Apache-2.0
// The OpenCL implementation of the per-frame stages (kernels/project.cl, kernels/blend.cl).
// Tables go to the device once (upload); each project()/blend() call is one upload of the
// chunk, one launch per output over all its frames, one read back. Chunk buffers are kept and
// only grow.

#include "cl_backends.h"

#include <algorithm>
#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape_kernels/blend_cl.h>
#include <drivenshape_kernels/project_cl.h>
#include <shared_types.h>

#include "cl_program.h"
#include "stage_checks.h"

namespace drivenshape {
namespace {

using cl_util::guard;

// Device rows are padded from n = 3V floats to a multiple of 4, so each row starts on a float4
// and the kernels never need a scalar tail. Padding is zero and never written:
//
//   host row   | x0 y0 z0 x1 | y1 z1 x2 y2 | z2 |           n = 9, rows packed
//   device row | x0 y0 z0 x1 | y1 z1 x2 y2 | z2 0  0  0 |   padded = 12
//
// Chunks move between the two layouts with rectangular copies (row pitch 4n vs 4 padded).
std::size_t paddedCount(std::size_t count) {
  return cl_util::roundUp(count, 4);
}

// Copies `rows` rows of `count` floats into a zero-padded block of `padded` floats per row.
std::vector<float> padRows(const float* data, std::size_t rows, std::size_t count,
                           std::size_t padded) {
  std::vector<float> out(rows * padded, 0.0f);
  for (std::size_t r = 0; r < rows; ++r) {
    std::copy(data + r * count, data + (r + 1) * count, out.begin() + r * padded);
  }
  return out;
}

class ClStages final : public StageBackend {
 public:
  ClStages(const cl_util::ClTarget& target)
      : mContext(target.context),
        mDevice(target.device),
        mQueue(target.queue),
        mTransfers(target.transfers) {
    mName = guard("querying the device name", [&] { return mDevice.getInfo<CL_DEVICE_NAME>(); });
    mProgram =
        cl_util::buildProgram(target, {{kernels::kProjectSourceName, kernels::kProjectSource},
                                       {kernels::kBlendSourceName, kernels::kBlendSource}});
    guard("creating the stage kernels", [&] {
      mProject = cl::Kernel(mProgram, "dsProject");
      mBlend = cl::Kernel(mProgram, "dsBlend");
    });
  }

  std::string name() const override { return mName; }

  void upload(const ShapeTables& tables) override {
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
    mDriverPadded = paddedCount(np);

    if (mBlendOnly) {
      guard("uploading the driven shapes",
            [&] { mDriven = makeBlendTable(tables.drivenShapes, nd); });
      mUploaded = true;
      return;
    }
    // Projection rows, padded to whole tiles with zero rows (the kernel's row loop is fixed).
    std::vector<float> rows = padRows(tables.projectionRows.data(),
                                      static_cast<std::size_t>(mRowCount), np, mDriverPadded);
    rows.resize(static_cast<std::size_t>(mTileCount) * DS_PROJECT_ROWS * mDriverPadded, 0.0f);
    std::vector<float> center = padRows(tables.center.data(), 1, np, mDriverPadded);

    guard("uploading the projection tables", [&] {
      mRows = readOnlyBuffer(rows);
      mCenter = readOnlyBuffer(center);
    });
    guard("uploading the driven shapes",
          [&] { mDriven = makeBlendTable(tables.drivenShapes, nd); });
    guard("uploading the driver shapes",
          [&] { mDriver = makeBlendTable(tables.driverShapes, np); });
    mUploaded = true;
  }

  void project(int frameCount, const float* driverFrames, float* projections,
               float* norms) override {
    checkProject(frameCount, driverFrames != nullptr, projections, norms);
    if (frameCount == 0) {
      return;
    }
    const std::size_t frames = static_cast<std::size_t>(frameCount);
    reserveFrames(frames);
    guard("uploading a chunk of driver frames",
          [&] { writeRows(mFrames.buffer, driverFrames, frames, mDriverCount, mDriverPadded); });
    projectFrames(frameCount, projections, norms);
  }

  void projectBlock(int frameCount, DeviceArray& driverFrames, float* projections,
                    float* norms) override {
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
    guard("copying a block of driver frames on the device", [&] {
      copyRows(cl_util::readBuffer(driverFrames), mDriverCount, mFrames.buffer, mDriverPadded,
               frames, mDriverCount);
    });
    projectFrames(frameCount, projections, norms);
  }

  void blend(int frameCount, const float* weights, float* driven, float* driver) override {
    checkBlend(frameCount, weights, driven != nullptr, driver != nullptr);
    if (frameCount == 0) {
      return;
    }
    uploadWeights(frameCount, weights);
    const std::size_t frames = static_cast<std::size_t>(frameCount);
    blendInto(mDriven, frameCount, mDrivenOut, "blending the driven shapes");
    guard("reading back blended shapes",
          [&] { readRows(mDrivenOut.buffer, driven, frames, mDriven.count, mDriven.padded); });
    if (driver != nullptr) {
      blendInto(mDriver, frameCount, mDriverOut, "blending the driver shapes");
      guard("reading back blended shapes",
            [&] { readRows(mDriverOut.buffer, driver, frames, mDriver.count, mDriver.padded); });
    }
  }

  void blendBlock(int frameCount, const float* weights, DeviceArray& driven,
                  DeviceArray* driver) override {
    if (!cl_util::onContext(mContext, driven) ||
        (driver != nullptr && !cl_util::onContext(mContext, *driver))) {
      StageBackend::blendBlock(frameCount, weights, driven, driver);
      return;
    }
    checkBlend(frameCount, weights, true, driver != nullptr);
    if (frameCount == 0) {
      return;
    }
    uploadWeights(frameCount, weights);
    blendOnDevice(mDriven, frameCount, mDrivenOut, driven, "blending the driven shapes");
    if (driver != nullptr) {
      blendOnDevice(mDriver, frameCount, mDriverOut, *driver, "blending the driver shapes");
    }
  }

 private:
  // A chunk-sized device buffer, reallocated only when a bigger chunk comes.
  struct ChunkBuffer {
    cl::Buffer buffer;
    std::size_t bytes = 0;
  };

  // One blendable mesh on the device: its shapes centred on `reference` (see blend.cl).
  struct BlendTable {
    cl::Buffer deltas;     // k x padded
    cl::Buffer reference;  // padded
    std::size_t count = 0;
    std::size_t padded = 0;
  };

  cl::Buffer readOnlyBuffer(std::vector<float>& data) {
    return cl::Buffer(mContext, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                      data.size() * sizeof(float), data.data());
  }

  BlendTable makeBlendTable(const std::vector<float>& shapes, std::size_t count) {
    const std::size_t k = static_cast<std::size_t>(mShapeCount);
    BlendTable table;
    table.count = count;
    table.padded = paddedCount(count);
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
        deltas[i * table.padded + j] = static_cast<float>(
            static_cast<double>(shapes[i * count + j]) - static_cast<double>(ref));
      }
    }
    table.deltas = readOnlyBuffer(deltas);
    table.reference = readOnlyBuffer(reference);
    return table;
  }

  void reserve(ChunkBuffer& chunk, std::size_t bytes, cl_mem_flags flags, bool zeroFill,
               const char* what) {
    if (chunk.bytes >= bytes) {
      return;
    }
    guard(what, [&] {
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
  void writeRows(const cl::Buffer& buffer, const float* data, std::size_t rows, std::size_t count,
                 std::size_t padded) {
    if (count == padded) {
      cl_util::upload(mQueue, mTransfers, buffer, CL_TRUE, 0, rows * count * sizeof(float), data);
      return;
    }
    const std::array<cl::size_type, 3> origin{0, 0, 0};
    const std::array<cl::size_type, 3> region{count * sizeof(float), rows, 1};
    mQueue.enqueueWriteBufferRect(buffer, CL_TRUE, origin, origin, region, padded * sizeof(float),
                                  0, count * sizeof(float), 0, data);
    cl_util::countTransfer(mTransfers, true, rows * count * sizeof(float));
  }

  // Device block (rows x padded) -> host block (rows x count, packed). Blocking.
  void readRows(const cl::Buffer& buffer, float* data, std::size_t rows, std::size_t count,
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

  void checkProject(int frameCount, bool framesPresent, const float* projections,
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

  void checkBlend(int frameCount, const float* weights, bool drivenPresent,
                  bool driverWanted) const {
    stage_checks::checkCall("blend", mUploaded, frameCount);
    if (mBlendOnly && driverWanted) {
      DS_THROW(kInternal,
               "StageBackend::blend of the driver needs the driver tables; these are "
               "blend-only");
    }
    if (frameCount > 0 && (weights == nullptr || !drivenPresent)) {
      DS_THROW(kInternal, "StageBackend::blend called with a null buffer");
    }
  }

  void reserveFrames(std::size_t frames) {
    reserve(mFrames, frames * mDriverPadded * sizeof(float), CL_MEM_READ_ONLY, true,
            "allocating the driver frame buffer");
  }

  /// dsProject on the frames in mFrames, then one read back of projections and norms.
  void projectFrames(int frameCount, float* projections, float* norms) {
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
    guard("running dsProject on a chunk of frames", [&] {
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
    guard("reading back the projections", [&] {
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

  /// Weights plus, per frame, sum(w) - 1 summed in double (the term that carries the reference
  /// shape in blend.cl, where float rounding of the sum would cost whole ulps of positions far
  /// from the origin), to the device.
  void uploadWeights(int frameCount, const float* weights) {
    const std::size_t frames = static_cast<std::size_t>(frameCount);
    const std::size_t k = static_cast<std::size_t>(mShapeCount);
    mStaging.resize(frames * (k + 1));
    for (std::size_t f = 0; f < frames; ++f) {
      double sum = 0.0;
      for (std::size_t i = 0; i < k; ++i) {
        mStaging[f * (k + 1) + i] = weights[f * k + i];
        sum += static_cast<double>(weights[f * k + i]);
      }
      mStaging[f * (k + 1) + k] = static_cast<float>(sum - 1.0);
    }
    reserve(mWeights, mStaging.size() * sizeof(float), CL_MEM_READ_ONLY, false,
            "allocating the weight buffer");
    guard("uploading a chunk of blend weights", [&] {
      cl_util::upload(mQueue, mTransfers, mWeights.buffer, CL_TRUE, 0,
                      mStaging.size() * sizeof(float), mStaging.data());
    });
  }

  /// Blends `table` with the uploaded weights into `out` (padded rows) and copies the rows,
  /// packed, into `result` on the device.
  void blendOnDevice(const BlendTable& table, int frameCount, ChunkBuffer& out, DeviceArray& result,
                     const char* what) {
    blendInto(table, frameCount, out, what);
    guard("copying blended shapes on the device", [&] {
      copyRows(out.buffer, table.padded, cl_util::writeBuffer(result), table.count,
               static_cast<std::size_t>(frameCount), table.count);
    });
  }

  /// Device-to-device copy of `rows` rows of `count` floats between blocks with row pitches
  /// `fromPitch` and `toPitch` (floats).
  void copyRows(const cl::Buffer& from, std::size_t fromPitch, const cl::Buffer& to,
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

  /// dsBlend of `table` with the uploaded weights into `out` (F x padded).
  void blendInto(const BlendTable& table, int frameCount, ChunkBuffer& out, const char* what) {
    const std::size_t frames = static_cast<std::size_t>(frameCount);
    reserve(out, frames * table.padded * sizeof(float), CL_MEM_READ_WRITE, false,
            "allocating a blend output buffer");
    DsBlendParams params{};
    params.quadCount = static_cast<int>(table.padded / 4);
    params.shapeCount = mShapeCount;
    params.frameCount = frameCount;
    params.weightStride = mShapeCount + 1;
    guard(what, [&] {
      mBlend.setArg(0, table.deltas);
      mBlend.setArg(1, table.reference);
      mBlend.setArg(2, mWeights.buffer);
      mBlend.setArg(3, out.buffer);
      mBlend.setArg(4, params);
      const std::size_t blocks = (frames + DS_BLEND_FRAMES - 1) / DS_BLEND_FRAMES;
      mQueue.enqueueNDRangeKernel(
          mBlend, cl::NullRange,
          cl::NDRange(cl_util::roundUp(static_cast<std::size_t>(params.quadCount), DS_LOCAL_SIZE),
                      blocks),
          cl::NDRange(DS_LOCAL_SIZE, 1));
    });
  }

  cl::Context mContext;
  cl::Device mDevice;
  cl::CommandQueue mQueue;
  cl_util::Transfers* mTransfers = nullptr;
  std::string mName;
  cl::Program mProgram;
  cl::Kernel mProject;
  cl::Kernel mBlend;

  bool mUploaded = false;
  int mShapeCount = 0;
  int mRowCount = 0;
  bool mBlendOnly = false;
  int mTileCount = 0;
  std::size_t mDriverCount = 0;
  std::size_t mDriverPadded = 0;
  cl::Buffer mRows;    // tileCount * DS_PROJECT_ROWS x padded, zero rows past k-1
  cl::Buffer mCenter;  // padded
  BlendTable mDriven;
  BlendTable mDriver;

  ChunkBuffer mFrames;     // F x padded driver frames (padding zeroed once)
  ChunkBuffer mProjected;  // F x (k+1): k-1 projections, ||b-m||^2, ||b||^2
  ChunkBuffer mWeights;    // F x (k+1): weights, sum(w) - 1
  ChunkBuffer mDrivenOut;  // F x padded driven
  ChunkBuffer mDriverOut;  // F x padded driver
  std::vector<float> mStaging;
};

}  // namespace

std::unique_ptr<StageBackend> makeClStages(const cl_util::ClTarget& target) {
  return std::make_unique<ClStages>(target);
}

std::unique_ptr<StageBackend> makeClStages(const cl::Context& context, const cl::Device& device,
                                           const cl::CommandQueue& queue) {
  return makeClStages(cl_util::ClTarget{context, device, queue});
}

}  // namespace drivenshape
