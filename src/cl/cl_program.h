#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include <CL/opencl.hpp>

namespace drivenshape::cl_util {

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

}  // namespace drivenshape::cl_util
