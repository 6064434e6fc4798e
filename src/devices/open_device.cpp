// SPDX-License-Identifier: Apache-2.0
// Listing the OpenCL devices and opening the one an application names (the command line's
// --device SPEC). The choice is always the caller's; "auto" is a rule the caller asks for.

#include <ostream>
#include <sstream>
#include <vector>

#include <drivenshape/device_cl.h>
#include <drivenshape/error.h>

#include "cl_backends.h"
#include "device_array.h"

namespace drivenshape {

DeviceArray Device::makeArray() {
  return DeviceArray();
}
namespace {

struct Found {
  cl::Platform platform;
  cl::Device device;
  OpenClDeviceInfo info;
};

std::string typeName(cl_device_type type) {
  if (type & CL_DEVICE_TYPE_GPU) {
    return "gpu";
  }
  if (type & CL_DEVICE_TYPE_CPU) {
    return "cpu";
  }
  if (type & CL_DEVICE_TYPE_ACCELERATOR) {
    return "accelerator";
  }
  return "other";
}

OpenClDeviceInfo describe(const cl::Platform& platform, const cl::Device& device, int index) {
  OpenClDeviceInfo info;
  info.index = index;
  info.name = device.getInfo<CL_DEVICE_NAME>();
  info.type = typeName(device.getInfo<CL_DEVICE_TYPE>());
  info.platform = platform.getInfo<CL_PLATFORM_NAME>();
  info.version = device.getInfo<CL_DEVICE_VERSION>();
  info.computeUnits = static_cast<int>(device.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());
  info.globalMemoryBytes = static_cast<std::int64_t>(device.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>());
  info.maxAllocationBytes =
      static_cast<std::int64_t>(device.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>());
  info.description =
      info.name + " [" + info.type + ", " + info.platform + ", " + info.version + "]";
  return info;
}

std::vector<Found> allDevices() {
  std::vector<Found> found;
  std::vector<cl::Platform> platforms;
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error&) {
    return found;  // no ICD or no platform: no devices
  }
  for (auto& platform : platforms) {
    std::vector<cl::Device> devices;
    try {
      platform.getDevices(CL_DEVICE_TYPE_ALL, &devices);
    } catch (const cl::Error&) {
      continue;
    }
    for (auto& device : devices) {
      try {
        found.push_back(
            {platform, device, describe(platform, device, static_cast<int>(found.size()))});
      } catch (const cl::Error&) {
        continue;  // a device that cannot be queried cannot be used either
      }
    }
  }
  return found;
}

/// The device `spec` names among `devices`, or null ("auto" with none: the host path).
const Found* choose(const std::vector<Found>& devices, const std::string& spec) {
  if (spec == "auto") {
    for (const auto& found : devices) {
      if (found.info.type == "gpu") {
        return &found;
      }
    }
    return devices.empty() ? nullptr : &devices.front();
  }
  if (spec == "cpu" || spec == "gpu") {
    for (const auto& found : devices) {
      if (found.info.type == spec) {
        return &found;
      }
    }
    return nullptr;
  }
  if (!spec.empty() && spec.size() <= 6 &&
      spec.find_first_not_of("0123456789") == std::string::npos) {
    const std::size_t index = std::stoul(spec);
    return index < devices.size() ? &devices[index] : nullptr;
  }
  for (const auto& found : devices) {
    if (found.info.name.find(spec) != std::string::npos) {
      return &found;
    }
  }
  return nullptr;
}

}  // namespace

std::vector<OpenClDeviceInfo> listOpenClDevices() {
  std::vector<OpenClDeviceInfo> infos;
  for (const Found& found : allDevices()) {
    infos.push_back(found.info);
  }
  return infos;
}

void printDevices(std::ostream& out) {
  const std::vector<OpenClDeviceInfo> devices = listOpenClDevices();
  if (devices.empty()) {
    out << "no OpenCL devices found (install pocl-opencl-icd for CPUs, or your GPU's OpenCL "
           "driver); `--device host` still works\n";
    return;
  }
  for (const OpenClDeviceInfo& info : devices) {
    out << info.index << ": " << info.description << "\n"
        << "   compute units " << info.computeUnits << ", global memory "
        << (info.globalMemoryBytes >> 20) << " MiB, max allocation "
        << (info.maxAllocationBytes >> 20) << " MiB\n";
  }
  out << "host: the reference path (plain C++, no OpenCL)\n";
}

std::unique_ptr<Device> openDevice(const std::string& spec, std::string* note) {
  if (spec == "host") {
    return makeHostDevice();
  }
  const std::vector<Found> devices = allDevices();
  const Found* chosen = choose(devices, spec);
  if (chosen == nullptr && spec == "auto") {
    if (note != nullptr) {
      *note =
          "no OpenCL device found; using the host reference path (slower). Install "
          "pocl-opencl-icd or a GPU driver for OpenCL.";
    }
    return makeHostDevice();
  }
  if (chosen == nullptr) {
    std::ostringstream available;
    printDevices(available);
    DS_THROW(kDevice, "no OpenCL device matches '", spec, "'. Available:\n", available.str());
  }
  try {
    const cl::Context context(chosen->device);
    const cl::CommandQueue queue(context, chosen->device);
    return makeOpenClDevice(context, chosen->device, queue, chosen->info.description);
  } catch (const cl::Error& error) {
    DS_THROW(kDevice, "cannot open OpenCL device ", chosen->info.description, ": ",
             clErrorName(error.err()));
  }
}

}  // namespace drivenshape
