// SPDX-License-Identifier: Apache-2.0
#pragma once

// A Device on an OpenCL context the application made itself (a DCC that already runs OpenCL,
// a farm wrapper that pins devices). Only this header exposes OpenCL types.

#include <memory>

#include <CL/opencl.hpp>

#include <drivenshape/device.h>

namespace drivenshape {

/// A Device on `device` of `context`, running every kernel on `queue` (which must be in-order).
/// Compiles nothing until a backend is made. Throws Error(kDevice) when the device cannot be
/// queried.
std::unique_ptr<Device> makeOpenClDevice(const cl::Context& context, const cl::Device& device,
                                         const cl::CommandQueue& queue);

}  // namespace drivenshape
