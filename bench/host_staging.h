// SPDX-License-Identifier: Apache-2.0
#pragma once

// For the benchmarks' before/after transfer counts: a Device whose backends take every block of
// frames through host memory, as the pipeline did before blocks stayed on the device (every
// kernel call uploads its inputs and reads its outputs back, and inside counts are made on the
// host, by the library's host backend). Results are the same bits.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/device.h>

#include "closest.h"
#include "stages.h"
#include "strain_limit.h"

namespace drivenshape::bench {

/// A closest-point backend reached only through its host-memory calls: the block calls run
/// ClosestBackend's defaults on the arrays' host copies, and inside counts are the library's
/// host backend's (makeHostClosest, on one thread, as the pipeline counted them before).
class HostStagingClosest final : public ClosestBackend {
 public:
  explicit HostStagingClosest(std::unique_ptr<ClosestBackend> inner)
      : mInner(std::move(inner)), mHost(makeHostClosest(hostOptions())) {}
  std::string name() const override { return mInner->name(); }
  void setSurface(const Mesh& driver, const BindingMask& mask) override {
    mInner->setSurface(driver, mask);
    mHost->setSurface(driver, mask);
  }
  void setSides(const std::vector<std::int8_t>& sides) override {
    mInner->setSides(sides);
    mHost->setSides(sides);
  }
  void setExitFade(float fade) override { mInner->setExitFade(fade); }
  void setAlongNormal(bool alongNormal) override { mInner->setAlongNormal(alongNormal); }
  void closest(int f, const float* poses, const float* points, SurfaceHit* hits) override {
    mInner->closest(f, poses, points, hits);
  }
  void transfer(int f, const SurfaceHit* hits, const float* from, const float* to,
                const float* points, float* out) override {
    mInner->transfer(f, hits, from, to, points, out);
  }
  void rebuild(int f, const SurfaceHit* hits, const float* to, const float* local,
               float* out) override {
    mInner->rebuild(f, hits, to, local, out);
  }
  void resolve(int f, const float* poses, const SurfaceHit* hits, float offset, float* points,
               int* moved) override {
    mInner->resolve(f, poses, hits, offset, points, moved);
  }
  void skinPlanes(int f, const float* poses, const SurfaceHit* hits, const std::int32_t* answered,
                  const float* points, float offset, float depth, float reach,
                  float* planes) override {
    mInner->skinPlanes(f, poses, hits, answered, points, offset, depth, reach, planes);
  }
  void countInside(int f, DeviceArray& poses, DeviceArray& hits, DeviceArray& points,
                   int* inside) override {
    mHost->countInside(f, poses, hits, points, inside);
  }

 private:
  static ClosestOptions hostOptions() {
    ClosestOptions options;
    options.threads = 1;
    return options;
  }

  std::unique_ptr<ClosestBackend> mInner;
  std::unique_ptr<ClosestBackend> mHost;  ///< the inside counts only
};

/// Projection and blend through their host-memory calls only.
class HostStagingStages final : public StageBackend {
 public:
  explicit HostStagingStages(std::unique_ptr<StageBackend> inner) : mInner(std::move(inner)) {}
  std::string name() const override { return mInner->name(); }
  void upload(const ShapeTables& tables) override { mInner->upload(tables); }
  void project(int f, const float* frames, float* projections, float* norms) override {
    mInner->project(f, frames, projections, norms);
  }
  void blend(int f, const float* weights, float* driven, float* driver) override {
    mInner->blend(f, weights, driven, driver);
  }

 private:
  std::unique_ptr<StageBackend> mInner;
};

/// `device` with host-staging backends and host-only arrays.
class HostStagingDevice final : public Device {
 public:
  explicit HostStagingDevice(Device& device) : mDevice(device) {}
  std::string description() const override { return mDevice.description(); }
  bool isOpenCl() const override { return mDevice.isOpenCl(); }
  std::unique_ptr<StageBackend> makeStages() override {
    return std::make_unique<HostStagingStages>(mDevice.makeStages());
  }
  std::unique_ptr<ClosestBackend> makeClosest(const ClosestOptions& options) override {
    return std::make_unique<HostStagingClosest>(mDevice.makeClosest(options));
  }
  std::unique_ptr<LayerBackend> makeLayers() override { return mDevice.makeLayers(); }
  std::unique_ptr<PositionMapBackend> makePositionMaps() override {
    return mDevice.makePositionMaps();
  }
  std::unique_ptr<StrainLimitBackend> makeStrainLimit(int threads) override {
    return mDevice.makeStrainLimit(threads);
  }
  TransferCounts transfers() const override { return mDevice.transfers(); }

 private:
  Device& mDevice;
};

}  // namespace drivenshape::bench
