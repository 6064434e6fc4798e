#pragma once

#include <iosfwd>
#include <memory>
#include <optional>
#include <string>

#include <drivenshape/cl_stages.h>

namespace drivenshape::cli {

/// One OpenCL device with the context and in-order queue the command line made for it.
struct ClDevice {
  cl::Context context;
  cl::Device device;
  cl::CommandQueue queue;
  std::string description;
};

/// Prints every platform and device with the index `--device` accepts.
void listDevices(std::ostream& out);

/// Picks the device for --device SPEC: "auto" (first GPU, else first device; nullopt if none),
/// "host" (nullopt: the reference path), "cpu", "gpu", a global index from `devices`, or a
/// substring of the device name. Throws Error(kDevice) when nothing matches, listing what
/// there is.
std::optional<ClDevice> chooseDevice(const std::string& spec);

/// The stage backend for --device SPEC (OpenCL or host). `description` receives its name.
std::unique_ptr<StageBackend> makeStages(const std::string& spec, std::string& description,
                                         std::ostream& log);

}  // namespace drivenshape::cli
