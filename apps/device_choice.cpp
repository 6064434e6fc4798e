#include "device_choice.h"

#include <ostream>
#include <sstream>
#include <vector>

#include <drivenshape/error.h>

namespace drivenshape::cli {
namespace {

struct Found {
  cl::Platform platform;
  cl::Device device;
};

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
      found.push_back({platform, device});
    }
  }
  return found;
}

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

std::string describe(const Found& found) {
  std::ostringstream text;
  text << found.device.getInfo<CL_DEVICE_NAME>() << " ["
       << typeName(found.device.getInfo<CL_DEVICE_TYPE>()) << ", "
       << found.platform.getInfo<CL_PLATFORM_NAME>() << ", "
       << found.device.getInfo<CL_DEVICE_VERSION>() << "]";
  return text.str();
}

}  // namespace

void listDevices(std::ostream& out) {
  const std::vector<Found> devices = allDevices();
  if (devices.empty()) {
    out << "no OpenCL devices found (install pocl-opencl-icd for CPUs, or your GPU's OpenCL "
           "driver); `--device host` still works\n";
    return;
  }
  for (std::size_t i = 0; i < devices.size(); ++i) {
    const cl::Device& device = devices[i].device;
    out << i << ": " << describe(devices[i]) << "\n"
        << "   compute units " << device.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>()
        << ", global memory " << (device.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>() >> 20)
        << " MiB, max allocation " << (device.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>() >> 20)
        << " MiB\n";
  }
  out << "host: the reference path (plain C++, no OpenCL)\n";
}

std::optional<ClDevice> chooseDevice(const std::string& spec) {
  if (spec == "host") {
    return std::nullopt;
  }
  const std::vector<Found> devices = allDevices();
  const Found* chosen = nullptr;
  if (spec == "auto") {
    for (const auto& found : devices) {
      if (found.device.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_GPU) {
        chosen = &found;
        break;
      }
    }
    if (chosen == nullptr && !devices.empty()) {
      chosen = &devices.front();
    }
    if (chosen == nullptr) {
      return std::nullopt;
    }
  } else if (spec == "cpu" || spec == "gpu") {
    const cl_device_type wanted = spec == "cpu" ? CL_DEVICE_TYPE_CPU : CL_DEVICE_TYPE_GPU;
    for (const auto& found : devices) {
      if (found.device.getInfo<CL_DEVICE_TYPE>() & wanted) {
        chosen = &found;
        break;
      }
    }
  } else if (!spec.empty() && spec.size() <= 6 &&
             spec.find_first_not_of("0123456789") == std::string::npos) {
    const std::size_t index = std::stoul(spec);
    if (index < devices.size()) {
      chosen = &devices[index];
    }
  } else {
    for (const auto& found : devices) {
      if (found.device.getInfo<CL_DEVICE_NAME>().find(spec) != std::string::npos) {
        chosen = &found;
        break;
      }
    }
  }
  if (chosen == nullptr) {
    std::ostringstream available;
    listDevices(available);
    DS_THROW(kDevice, "no OpenCL device matches --device '", spec, "'. Available:\n",
             available.str());
  }
  try {
    ClDevice result;
    result.device = chosen->device;
    result.context = cl::Context(chosen->device);
    result.queue = cl::CommandQueue(result.context, chosen->device);
    result.description = describe(*chosen);
    return result;
  } catch (const cl::Error& error) {
    DS_THROW(kDevice, "cannot open OpenCL device ", describe(*chosen), ": ",
             clErrorName(error.err()));
  }
}

DeviceBackends makeBackends(const std::string& spec, std::ostream& log, int threads) {
  DeviceBackends backends;
  ClosestOptions search;
  search.threads = threads;
  backends.device = chooseDevice(spec);
  if (!backends.device) {
    if (spec == "auto") {
      log << "warning: no OpenCL device found; using the host reference path (slower). "
             "Install pocl-opencl-icd or a GPU driver for OpenCL.\n";
    }
    backends.description = "host (reference path, no OpenCL)";
    backends.stages = makeHostStages();
    backends.binding = makeHostClosest(search);
    backends.audit = makeHostClosest(search);
    backends.layers = makeHostLayers();
    return backends;
  }
  const ClDevice& d = *backends.device;
  backends.description = d.description;
  backends.stages = makeClStages(d.context, d.device, d.queue);
  backends.binding = makeClClosest(d.context, d.device, d.queue, search);
  backends.audit = makeClClosest(d.context, d.device, d.queue, search);
  backends.layers = makeClLayers(d.context, d.device, d.queue);
  return backends;
}

}  // namespace drivenshape::cli
