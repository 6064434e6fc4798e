// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <CL/opencl.hpp>

#include "device_array.h"

namespace drivenshape::cl_util {

/// Host<->device copies made by the backends of one device: counted so that benchmarks can
/// show how much a batch moves (drivenshape::Device::transfers()).
struct Transfers {
  std::atomic<std::int64_t> uploads{0};
  std::atomic<std::int64_t> downloads{0};
  std::atomic<std::int64_t> uploadBytes{0};
  std::atomic<std::int64_t> downloadBytes{0};
};

/// Programs already built on one device, by their full source text and defines: every backend
/// of a drivenshape::Device shares them, so each program is compiled once per device.
class ProgramCache {
 public:
  /// The cached program for `key`, or the result of `build()` stored under it.
  template <typename Build>
  cl::Program get(const std::string& key, Build&& build) {
    std::lock_guard<std::mutex> lock(mMutex);
    auto found = mPrograms.find(key);
    if (found == mPrograms.end()) {
      found = mPrograms.emplace(key, build()).first;
    }
    return found->second;
  }
  std::size_t size() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return mPrograms.size();
  }

 private:
  mutable std::mutex mMutex;
  std::map<std::string, cl::Program> mPrograms;
};

/// Where an OpenCL backend runs: the caller's context, device and in-order queue, and (when
/// the backend belongs to a drivenshape::Device) the device's program cache and transfer
/// counters. Null pointers: build programs afresh, count nothing.
struct ClTarget {
  cl::Context context;
  cl::Device device;
  cl::CommandQueue queue;
  ProgramCache* programs = nullptr;
  Transfers* transfers = nullptr;
};

/// A read-only device buffer holding a copy of `data`. An empty table gets one zero element,
/// so that a kernel argument is always a valid buffer.
template <typename T>
cl::Buffer readOnlyBuffer(const cl::Context& context, const std::vector<T>& data) {
  const T zero{};
  const void* source = data.empty() ? static_cast<const void*>(&zero) : data.data();
  const std::size_t bytes = std::max<std::size_t>(1, data.size()) * sizeof(T);
  return cl::Buffer(context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, bytes,
                    const_cast<void*>(source));
}

/// One embedded kernel source (from the generated headers in drivenshape_kernels/).
struct KernelSource {
  const char* name;  ///< file name, for build logs
  const char* text;  ///< NUL-terminated OpenCL C
};

/// Builds a program from kernels/shared_types.h followed by `sources`, for `device`, with
/// `-cl-std=CL1.2` and a `#define` preamble made from `defines` ("NAME=VALUE" or "NAME").
/// On failure throws Error(kDevice) naming the sources, with the device's build log.
cl::Program buildProgram(const cl::Context& context, const cl::Device& device,
                         const std::vector<KernelSource>& sources,
                         const std::vector<std::string>& defines = {});

/// The same program from `target`'s cache when it has one (built and stored on first use).
cl::Program buildProgram(const ClTarget& target, const std::vector<KernelSource>& sources,
                         const std::vector<std::string>& defines = {});

/// Counts one host-to-device (`toDevice`) or device-to-host copy of `bytes` in `transfers`
/// (nothing when it is null).
inline void countTransfer(Transfers* transfers, bool toDevice, std::size_t bytes) {
  if (transfers == nullptr) {
    return;
  }
  ++(toDevice ? transfers->uploads : transfers->downloads);
  (toDevice ? transfers->uploadBytes : transfers->downloadBytes) +=
      static_cast<std::int64_t>(bytes);
}

/// enqueueWriteBuffer / enqueueReadBuffer, counted in `transfers`.
inline void upload(cl::CommandQueue& queue, Transfers* transfers, const cl::Buffer& buffer,
                   cl_bool blocking, std::size_t offset, std::size_t bytes, const void* data) {
  queue.enqueueWriteBuffer(buffer, blocking, offset, bytes, data);
  countTransfer(transfers, true, bytes);
}
inline void download(cl::CommandQueue& queue, Transfers* transfers, const cl::Buffer& buffer,
                     cl_bool blocking, std::size_t offset, std::size_t bytes, void* data) {
  queue.enqueueReadBuffer(buffer, blocking, offset, bytes, data);
  countTransfer(transfers, false, bytes);
}

/// Runs `body`, turning a cl::Error into Error(kDevice) whose message names `what`, the
/// failed call and its status ("CL_OUT_OF_RESOURCES").
template <typename Body>
auto guard(const char* what, Body&& body) -> decltype(body());

/// Throws Error(kDevice) for a cl::Error raised while doing `what`.
[[noreturn]] void rethrowClError(const char* what, const cl::Error& error);

template <typename Body>
auto guard(const char* what, Body&& body) -> decltype(body()) {
  try {
    return body();
  } catch (const cl::Error& error) {
    rethrowClError(what, error);
  }
}

/// Rounds `count` up to a multiple of `multiple` (global sizes for an explicit local size).
inline std::size_t roundUp(std::size_t count, std::size_t multiple) {
  return (count + multiple - 1) / multiple * multiple;
}

/// Sets the arguments of `kernel` in order: buffers, or plain values such as a params struct
/// (passed by value, sizeof(T) bytes).
template <typename... Args>
void setArgs(cl::Kernel& kernel, const Args&... args) {
  cl_uint index = 0;
  (kernel.setArg(index++, args), ...);
}

/// Enqueues `kernel` on `items` work items in a 1-D range, rounded up to whole work-groups of
/// `localSize` (kernels return early past their last item).
inline void enqueue1d(cl::CommandQueue& queue, const cl::Kernel& kernel, std::size_t items,
                      std::size_t localSize) {
  queue.enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(roundUp(items, localSize)),
                             cl::NDRange(localSize));
}

/// A device buffer for chunks of frames: it grows to the largest size asked for (at least 16
/// bytes, so it can always be bound) and is then reused.
class GrowingBuffer {
 public:
  explicit GrowingBuffer(cl_mem_flags flags) : mFlags(flags) {}

  /// The buffer, reallocated first when it holds fewer than `bytes`. May throw cl::Error.
  cl::Buffer& reserve(const cl::Context& context, std::size_t bytes) {
    bytes = std::max<std::size_t>(bytes, 16);
    if (bytes > mBytes) {
      mBuffer = cl::Buffer(context, mFlags, bytes);
      mBytes = bytes;
    }
    return mBuffer;
  }

 private:
  cl_mem_flags mFlags;
  cl::Buffer mBuffer;
  std::size_t mBytes = 0;
};

/// The device side of a DeviceArray on one OpenCL context: a growing buffer, copies counted
/// in the device's transfers.
class ClStorage final : public DeviceStorage {
 public:
  ClStorage(const cl::Context& context, const cl::CommandQueue& queue, Transfers* transfers)
      : mContext(context), mQueue(queue), mTransfers(transfers) {}

  void reserve(std::size_t bytes) override;
  void upload(const void* host, std::size_t bytes) override;
  void download(void* host, std::size_t bytes) override;

  cl::Buffer& buffer() { return mBuffer; }
  const cl::Context& context() const { return mContext; }

 private:
  cl::Context mContext;
  cl::CommandQueue mQueue;
  Transfers* mTransfers;
  cl::Buffer mBuffer;
  std::size_t mBytes = 0;
};

/// The OpenCL buffer behind `storage` when it is a ClStorage on `context`, else null (an array
/// of the host device, or of another context: the caller then works on the host copy).
cl::Buffer* bufferOf(DeviceStorage* storage, const cl::Context& context);

/// True when every array has an OpenCL side on `context`.
template <typename... Arrays>
bool onContext(const cl::Context& context, Arrays&... arrays) {
  return ((bufferOf(arrays.storage(), context) != nullptr) && ...);
}

/// The buffer of `array` for reading, writing or modifying it on the device (see
/// DeviceArray::deviceForRead etc.); only for arrays onContext() accepted.
inline cl::Buffer& readBuffer(DeviceArray& array) {
  return static_cast<ClStorage*>(array.deviceForRead())->buffer();
}
inline cl::Buffer& writeBuffer(DeviceArray& array) {
  return static_cast<ClStorage*>(array.deviceForWrite())->buffer();
}
inline cl::Buffer& modifyBuffer(DeviceArray& array) {
  return static_cast<ClStorage*>(array.deviceForModify())->buffer();
}

}  // namespace drivenshape::cl_util
