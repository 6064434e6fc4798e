// SPDX-License-Identifier: Apache-2.0
#pragma once

// The OpenCL device of the micro-benchmarks that drive one backend directly (bench_stages,
// bench_correction): the first device, or the first whose name contains --device, with a
// context and an in-order queue. The library never picks a device; these programs do.

#include <string>
#include <vector>

#include <CL/opencl.hpp>

#include <drivenshape/error.h>

namespace drivenshape::bench {

struct OpenClQueue {
  cl::Device device;
  cl::Context context;
  cl::CommandQueue queue;
};

/// The first device of any platform whose CL_DEVICE_NAME contains `name` (every name contains
/// ""). Throws Error(kDevice) when there is none.
inline OpenClQueue openClQueue(const std::string& name) {
  std::vector<cl::Platform> platforms;
  cl::Platform::get(&platforms);
  for (cl::Platform& platform : platforms) {
    std::vector<cl::Device> devices;
    platform.getDevices(CL_DEVICE_TYPE_ALL, &devices);
    for (cl::Device& candidate : devices) {
      if (candidate.getInfo<CL_DEVICE_NAME>().find(name) != std::string::npos) {
        cl::Context context(candidate);
        cl::CommandQueue queue(context, candidate);
        return {candidate, context, queue};
      }
    }
  }
  DS_THROW(kDevice, "no OpenCL device", name.empty() ? "" : " matching ", name);
}

}  // namespace drivenshape::bench
