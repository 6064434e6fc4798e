// SPDX-License-Identifier: Apache-2.0
#pragma once

// Where the per-frame stages run. A Device creates the backend of every stage on one compute
// device: the host reference path (plain C++) or one OpenCL device. The library never chooses a
// device on its own: the application does, with makeHostDevice(), openDevice(spec) or (with its
// own OpenCL context) makeOpenClDevice() in drivenshape/device_cl.h.

#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/layer_backend.h>
#include <drivenshape/position_map_backend.h>

namespace drivenshape {

// The backends a device makes and the arrays they share are private to the library
// (src/devices/stages.h, src/devices/closest.h, src/core/device_array.h): an application holds
// a Device and hands it to the Evaluator, the bake or the position maps.
class StageBackend;
class ClosestBackend;
class StrainLimitBackend;
struct ClosestOptions;
class DeviceArray;

/// Host<->device copies made by a device's backends since it was created (zero on the host).
struct TransferCounts {
  std::int64_t uploads = 0;
  std::int64_t downloads = 0;
  std::int64_t uploadBytes = 0;
  std::int64_t downloadBytes = 0;
};

/// One compute device and the backends of every stage on it. Each OpenCL program is compiled
/// once per Device and shared by all the backends it makes. Backends are independent objects
/// (each is single-threaded); the Device must outlive them. make*() may be called from several
/// threads; each backend then belongs to its caller's thread.
class Device {
 public:
  virtual ~Device() = default;
  /// "host (reference path, no OpenCL)" or the OpenCL device's description.
  virtual std::string description() const = 0;
  /// True for an OpenCL device.
  virtual bool isOpenCl() const = 0;

  /// Projection and blend of the database shapes.
  virtual std::unique_ptr<StageBackend> makeStages() = 0;
  /// Exact closest triangles, local-frame transfer and rebuild, penetration resolution.
  virtual std::unique_ptr<ClosestBackend> makeClosest(const ClosestOptions& options) = 0;
  /// Layers: mix and wind.
  virtual std::unique_ptr<LayerBackend> makeLayers() = 0;
  /// Position maps.
  virtual std::unique_ptr<PositionMapBackend> makePositionMaps() = 0;
  /// The strain limit; `threads` host threads for the host reference (0 = one per hardware
  /// thread).
  virtual std::unique_ptr<StrainLimitBackend> makeStrainLimit(int threads) = 0;

  /// An empty array whose device side (if this device has one) the backends made here read
  /// and write in place: the evaluator keeps a block of frames in such arrays between stages.
  virtual DeviceArray makeArray();

  /// Copies between host and device so far (benchmarks show them per batch).
  virtual TransferCounts transfers() const { return {}; }
  /// OpenCL programs compiled on this device so far (0 on the host).
  virtual int programsBuilt() const { return 0; }
};

/// The host reference path: plain C++, double arithmetic where it matters, no OpenCL.
std::unique_ptr<Device> makeHostDevice();

/// One OpenCL device as the system lists it.
struct OpenClDeviceInfo {
  int index = 0;         ///< global index over every platform (what openDevice accepts)
  std::string name;      ///< CL_DEVICE_NAME
  std::string type;      ///< "gpu", "cpu", "accelerator" or "other"
  std::string platform;  ///< CL_PLATFORM_NAME
  std::string version;   ///< CL_DEVICE_VERSION
  int computeUnits = 0;
  std::int64_t globalMemoryBytes = 0;
  std::int64_t maxAllocationBytes = 0;
  std::string description;  ///< "name [type, platform, version]"
};

/// Every OpenCL device of every platform (empty when there is no OpenCL runtime).
std::vector<OpenClDeviceInfo> listOpenClDevices();

/// Prints listOpenClDevices() with the indices openDevice accepts, and the host path.
void printDevices(std::ostream& out);

/// Opens the device the caller names: "host" (the reference path), "auto" (the first GPU, else
/// the first OpenCL device, else the host path), "cpu", "gpu", a global index from
/// listOpenClDevices(), or a substring of a device name. When "auto" finds no OpenCL device and
/// `note` is not null, *note says so (the host path is then much slower). Throws
/// Error(kDevice), listing the devices there are, when nothing matches or the device cannot be
/// opened.
std::unique_ptr<Device> openDevice(const std::string& spec, std::string* note = nullptr);

}  // namespace drivenshape
