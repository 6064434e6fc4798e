#pragma once

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

}  // namespace drivenshape::cl_util
