// SPDX-License-Identifier: Apache-2.0
// The host reference path as a Device: every backend in plain C++.

#include <drivenshape/device.h>

#include "closest.h"
#include "stages.h"
#include "strain_limit.h"

namespace drivenshape {
namespace {

class HostDevice final : public Device {
 public:
  std::string description() const override { return "host (reference path, no OpenCL)"; }
  bool isOpenCl() const override { return false; }
  std::unique_ptr<StageBackend> makeStages() override { return makeHostStages(); }
  std::unique_ptr<ClosestBackend> makeClosest(const ClosestOptions& options) override {
    return makeHostClosest(options);
  }
  std::unique_ptr<LayerBackend> makeLayers() override { return makeHostLayers(); }
  std::unique_ptr<PositionMapBackend> makePositionMaps() override { return makeHostPositionMaps(); }
  std::unique_ptr<StrainLimitBackend> makeStrainLimit(int threads) override {
    return makeHostStrainLimit(threads);
  }
};

}  // namespace

std::unique_ptr<Device> makeHostDevice() {
  return std::make_unique<HostDevice>();
}

}  // namespace drivenshape
