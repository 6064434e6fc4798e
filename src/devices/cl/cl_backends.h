// SPDX-License-Identifier: Apache-2.0
#pragma once

// The OpenCL backends of every stage (private to the library: applications reach them through
// drivenshape::Device, see drivenshape/device.h and drivenshape/device_cl.h). The library never
// picks a device: the caller passes the context, device and an in-order queue. Programs are
// built with -cl-std=CL1.2, once per device when the target carries a program cache; a build
// failure throws Error(kDevice) with the build log.

#include <memory>
#include <string>

#include <CL/opencl.hpp>

#include <drivenshape/device.h>
#include <drivenshape/layer_backend.h>
#include <drivenshape/position_map_backend.h>

#include "closest.h"
#include "stages.h"
#include "strain_limit.h"

#include "cl_program.h"

namespace drivenshape {

/// Projection and blend (kernels/project.cl, kernels/blend.cl; cl_stages.h).
std::unique_ptr<StageBackend> makeClStages(const cl_util::ClTarget& target);
/// Closest triangles, transfer, rebuild, the clearance certificate, resolution
/// (kernels/closest.cl, bvh.cl, transfer.cl, certificate.cl, resolve.cl; cl_closest.h).
std::unique_ptr<ClosestBackend> makeClClosest(const cl_util::ClTarget& target,
                                              const ClosestOptions& options = {});
/// Mix and wind (kernels/mix.cl, kernels/wind.cl; cl_layers.h).
std::unique_ptr<LayerBackend> makeClLayers(const cl_util::ClTarget& target);
/// Position maps (kernels/posmap.cl; cl_posmap.cpp).
std::unique_ptr<PositionMapBackend> makeClPositionMaps(const cl_util::ClTarget& target);
/// The strain limit (kernels/strain_limit.cl; cl_strain_limit.cpp).
std::unique_ptr<StrainLimitBackend> makeClStrainLimit(const cl_util::ClTarget& target);

// The same on a bare context, device and queue (no program cache, no transfer counts): for
// tests of one backend.
std::unique_ptr<StageBackend> makeClStages(const cl::Context& context, const cl::Device& device,
                                           const cl::CommandQueue& queue);
std::unique_ptr<ClosestBackend> makeClClosest(const cl::Context& context, const cl::Device& device,
                                              const cl::CommandQueue& queue,
                                              const ClosestOptions& options = {});
std::unique_ptr<LayerBackend> makeClLayers(const cl::Context& context, const cl::Device& device,
                                           const cl::CommandQueue& queue);
std::unique_ptr<PositionMapBackend> makeClPositionMaps(const cl::Context& context,
                                                       const cl::Device& device,
                                                       const cl::CommandQueue& queue);
std::unique_ptr<StrainLimitBackend> makeClStrainLimit(const cl::Context& context,
                                                      const cl::Device& device,
                                                      const cl::CommandQueue& queue);

/// A Device on the caller's context (drivenshape/device_cl.h) with the description openDevice()
/// makes for it.
std::unique_ptr<Device> makeOpenClDevice(const cl::Context& context, const cl::Device& device,
                                         const cl::CommandQueue& queue,
                                         const std::string& description);

/// Turns an OpenCL status code into its name ("CL_OUT_OF_RESOURCES"); unknown codes as "OpenCL
/// status N".
const char* clErrorName(int status);

}  // namespace drivenshape
