#pragma once

// For the benchmarks' before/after transfer counts: a Device whose closest-point backends ignore
// ClosestBackend::keepPoses(), so that every call uploads its own poses, as every call did
// before the pipeline kept a batch's driver on the device. Results are the same bits.

#include <memory>
#include <string>

#include <drivenshape/device.h>

namespace drivenshape::cli {

/// A closest-point backend that ignores keepPoses(): every call uploads its own poses, as every
/// call did before the pipeline kept a batch's driver on the device. For the before/after
/// transfer counts only; results are the same bits.
class UploadEveryCall final : public ClosestBackend {
 public:
  explicit UploadEveryCall(std::unique_ptr<ClosestBackend> inner) : mInner(std::move(inner)) {}
  std::string name() const override { return mInner->name(); }
  void setSurface(const Mesh& driver, const BindingMask& mask) override {
    mInner->setSurface(driver, mask);
  }
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

 private:
  std::unique_ptr<ClosestBackend> mInner;
};

/// `device` with UploadEveryCall closest-point backends.
class UploadEveryCallDevice final : public Device {
 public:
  explicit UploadEveryCallDevice(Device& device) : mDevice(device) {}
  std::string description() const override { return mDevice.description(); }
  bool isOpenCl() const override { return mDevice.isOpenCl(); }
  std::unique_ptr<StageBackend> makeStages() override { return mDevice.makeStages(); }
  std::unique_ptr<ClosestBackend> makeClosest(const ClosestOptions& options) override {
    return std::make_unique<UploadEveryCall>(mDevice.makeClosest(options));
  }
  std::unique_ptr<LayerBackend> makeLayers() override { return mDevice.makeLayers(); }
  std::unique_ptr<PositionMapBackend> makePositionMaps() override {
    return mDevice.makePositionMaps();
  }
  TransferCounts transfers() const override { return mDevice.transfers(); }

 private:
  Device& mDevice;
};

}  // namespace drivenshape::cli
