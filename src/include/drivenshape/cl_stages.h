#pragma once

#include <memory>
#include <string>
#include <vector>

#include <CL/opencl.hpp>

#include <drivenshape/stages.h>

namespace drivenshape {

/// The OpenCL implementation of StageBackend. The library never picks a device: the caller
/// passes the context, device and an in-order queue (the command line chooses them with
/// --device). Programs are built once here, with -cl-std=CL1.2; a build failure throws
/// Error(kDevice) with the build log.
std::unique_ptr<StageBackend> makeClStages(const cl::Context& context, const cl::Device& device,
                                           const cl::CommandQueue& queue);

/// Turns an OpenCL status code into its name ("CL_OUT_OF_RESOURCES"); unknown codes as "OpenCL
/// status N".
const char* clErrorName(int status);

}  // namespace drivenshape
