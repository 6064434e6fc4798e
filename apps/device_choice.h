#pragma once

#include <iosfwd>
#include <memory>
#include <optional>
#include <string>

#include <drivenshape/bake.h>
#include <drivenshape/cl_stages.h>
#include <drivenshape/correction.h>
#include <drivenshape/layers.h>

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

/// Every backend a bake needs, on one device, owned together.
struct DeviceBackends {
  std::string description;
  std::optional<ClDevice> device;  ///< empty for the host path
  std::unique_ptr<StageBackend> stages;
  std::unique_ptr<ClosestBackend> binding;
  std::unique_ptr<ClosestBackend> audit;
  std::unique_ptr<LayerBackend> layers;  ///< mix and wind (LayerStack)

  BakeBackends view() const { return {stages.get(), binding.get(), audit.get(), layers.get()}; }
};

/// The backends for --device SPEC (OpenCL or host); `log` gets a warning when `auto` finds no
/// OpenCL device and falls back to the host path.
/// `threads` caps the host threads of the closest-triangle search (0 = all cores).
DeviceBackends makeBackends(const std::string& spec, std::ostream& log, int threads = 0);

}  // namespace drivenshape::cli
