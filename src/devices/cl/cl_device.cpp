// SPDX-License-Identifier: Apache-2.0
// One OpenCL device as a Device: its backends share the device's program cache (each program
// compiled once) and its transfer counters.

#include <memory>
#include <sstream>

#include <drivenshape/device_cl.h>
#include <drivenshape/error.h>

#include "cl_backends.h"
#include "cl_program.h"

namespace drivenshape {
namespace {

class ClDevice final : public Device {
 public:
  ClDevice(const cl::Context& context, const cl::Device& device, const cl::CommandQueue& queue,
           std::string description)
      : mDescription(std::move(description)) {
    mTarget.context = context;
    mTarget.device = device;
    mTarget.queue = queue;
    mTarget.programs = &mPrograms;
    mTarget.transfers = &mTransfers;
  }

  std::string description() const override { return mDescription; }
  bool isOpenCl() const override { return true; }
  std::unique_ptr<StageBackend> makeStages() override { return makeClStages(mTarget); }
  std::unique_ptr<ClosestBackend> makeClosest(const ClosestOptions& options) override {
    return makeClClosest(mTarget, options);
  }
  std::unique_ptr<LayerBackend> makeLayers() override { return makeClLayers(mTarget); }
  std::unique_ptr<PositionMapBackend> makePositionMaps() override {
    return makeClPositionMaps(mTarget);
  }
  std::unique_ptr<StrainLimitBackend> makeStrainLimit(int /*threads*/) override {
    return makeClStrainLimit(mTarget);
  }
  DeviceArray makeArray() override {
    return DeviceArray(
        std::make_unique<cl_util::ClStorage>(mTarget.context, mTarget.queue, &mTransfers));
  }
  TransferCounts transfers() const override {
    return {mTransfers.uploads.load(), mTransfers.downloads.load(), mTransfers.uploadBytes.load(),
            mTransfers.downloadBytes.load()};
  }
  int programsBuilt() const override { return static_cast<int>(mPrograms.size()); }

 private:
  std::string mDescription;
  cl_util::ProgramCache mPrograms;
  cl_util::Transfers mTransfers;
  cl_util::ClTarget mTarget;
};

}  // namespace

std::unique_ptr<Device> makeOpenClDevice(const cl::Context& context, const cl::Device& device,
                                         const cl::CommandQueue& queue) {
  const std::string name =
      cl_util::guard("querying the device name", [&] { return device.getInfo<CL_DEVICE_NAME>(); });
  return std::make_unique<ClDevice>(context, device, queue, name);
}

std::unique_ptr<Device> makeOpenClDevice(const cl::Context& context, const cl::Device& device,
                                         const cl::CommandQueue& queue,
                                         const std::string& description) {
  return std::make_unique<ClDevice>(context, device, queue, description);
}

}  // namespace drivenshape
