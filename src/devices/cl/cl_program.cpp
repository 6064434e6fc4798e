// SPDX-License-Identifier: Apache-2.0
#include "cl_program.h"

#include <algorithm>
#include <sstream>

#include <drivenshape/error.h>
#include <drivenshape_kernels/shared_types_cl.h>
#include "cl_backends.h"

namespace drivenshape::cl_util {

void rethrowClError(const char* what, const cl::Error& error) {
  DS_THROW(kDevice, "OpenCL failed while ", what, ": ", error.what(), " returned ",
           clErrorName(error.err()),
           error.err() == CL_OUT_OF_RESOURCES || error.err() == CL_MEM_OBJECT_ALLOCATION_FAILURE
               ? "; evaluate fewer frames per call (a smaller batch) or use another device"
               : "");
}

void ClStorage::reserve(std::size_t bytes) {
  bytes = std::max<std::size_t>(bytes, 16);
  if (bytes > mBytes) {
    guard("allocating a frame block on the device",
          [&] { mBuffer = cl::Buffer(mContext, CL_MEM_READ_WRITE, bytes); });
    mBytes = bytes;
  }
}

void ClStorage::upload(const void* host, std::size_t bytes) {
  guard("copying a frame block to the device",
        [&] { cl_util::upload(mQueue, mTransfers, mBuffer, CL_TRUE, 0, bytes, host); });
}

void ClStorage::download(void* host, std::size_t bytes) {
  guard("copying a frame block from the device",
        [&] { cl_util::download(mQueue, mTransfers, mBuffer, CL_TRUE, 0, bytes, host); });
}

cl::Buffer* bufferOf(DeviceStorage* storage, const cl::Context& context) {
  auto* cl = dynamic_cast<ClStorage*>(storage);
  return cl != nullptr && cl->context()() == context() ? &cl->buffer() : nullptr;
}

namespace {

/// The text of a program: the defines, the shared types, then the sources with #line markers.
std::string programText(const std::vector<KernelSource>& sources,
                        const std::vector<std::string>& defines) {
  std::ostringstream text;
  for (const std::string& define : defines) {
    const auto eq = define.find('=');
    if (eq == std::string::npos) {
      text << "#define " << define << "\n";
    } else {
      text << "#define " << define.substr(0, eq) << " " << define.substr(eq + 1) << "\n";
    }
  }
  text << kernels::kSharedTypesSource << "\n";
  for (const KernelSource& source : sources) {
    text << "#line 1 \"" << source.name << "\"\n" << source.text << "\n";
  }
  return text.str();
}

std::string sourceNames(const std::vector<KernelSource>& sources) {
  std::string names;
  for (const KernelSource& source : sources) {
    names += names.empty() ? source.name : std::string(", ") + source.name;
  }
  return names;
}

}  // namespace

cl::Program buildProgram(const ClTarget& target, const std::vector<KernelSource>& sources,
                         const std::vector<std::string>& defines) {
  if (target.programs == nullptr) {
    return buildProgram(target.context, target.device, sources, defines);
  }
  return target.programs->get(programText(sources, defines), [&] {
    return buildProgram(target.context, target.device, sources, defines);
  });
}

cl::Program buildProgram(const cl::Context& context, const cl::Device& device,
                         const std::vector<KernelSource>& sources,
                         const std::vector<std::string>& defines) {
  const std::string program_text = programText(sources, defines);
  const std::string names = sourceNames(sources);
  cl::Program program;
  try {
    program = cl::Program(context, program_text);
  } catch (const cl::Error& error) {
    rethrowClError("creating the program", error);
  }
  try {
    program.build({device}, "-cl-std=CL1.2");
  } catch (const cl::Error& error) {
    std::string log;
    try {
      log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(device);
    } catch (const cl::Error&) {
      log = "(no build log available)";
    }
    DS_THROW(kDevice, "OpenCL build of ", names, " failed on '", device.getInfo<CL_DEVICE_NAME>(),
             "' (", clErrorName(error.err()), "). Build log:\n", log);
  }
  return program;
}

}  // namespace drivenshape::cl_util
