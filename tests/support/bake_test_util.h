// SPDX-License-Identifier: Apache-2.0
#pragma once

// Helpers shared by the bake suites: the bundled sample shot (a slice of the sleeve scene), its
// databases, and the backends of a bake on the host or an OpenCL device.

#include <memory>
#include <string>
#include <vector>

#include <drivenshape/bake.h>
#include <drivenshape/database.h>
#include <drivenshape/database_build.h>
#include <drivenshape/device.h>
#include <drivenshape/device_cl.h>
#include <drivenshape/point_cache.h>

#include "closest.h"

#include "stages.h"
#include "strain_limit.h"
#include "test_support.h"

namespace drivenshape::testing {

/// A file of the bundled sample shot (tests/data/sleeve).
inline std::string sample(const std::string& name) {
  return dataDir() + "/sleeve/" + name;
}

/// A database of `count` shapes from the sample's train clip, seeded with `addFrames` if any;
/// without the pose model unless `poseModel` (the default settings then run the QP, what most
/// bake tests are about; tests/database/test_pose_model.cpp tests the model).
inline Database buildSample(int count, const std::vector<int>& addFrames = {},
                            bool poseModel = false) {
  const Mesh driver = readObj(sample("driver_rest.obj"));
  const Mesh driven = readObj(sample("driven_rest.obj"));
  const auto driverCache = openPointCache(sample("train.driver.pc2"));
  const auto drivenCache = openPointCache(sample("train.driven.pc2"));
  DatabaseBuildOptions options;
  options.count = count;
  options.addFrames = addFrames;
  options.poseModel = poseModel;
  return buildDatabase(driver, driven, *driverCache, *drivenCache, options);
}

/// The sample's rest meshes and its two clips' caches (train, the reference; test, the shot),
/// for tests that build a database from both clips.
struct SampleClips {
  Mesh driver = readObj(sample("driver_rest.obj"));
  Mesh driven = readObj(sample("driven_rest.obj"));
  std::unique_ptr<PointCacheReader> trainDriver = openPointCache(sample("train.driver.pc2"));
  std::unique_ptr<PointCacheReader> trainDriven = openPointCache(sample("train.driven.pc2"));
  std::unique_ptr<PointCacheReader> testDriver = openPointCache(sample("test.driver.pc2"));
  std::unique_ptr<PointCacheReader> testDriven = openPointCache(sample("test.driven.pc2"));
};

/// The 30-shape database of the sample, built once per test binary.
inline const Database& sampleDatabase() {
  static const Database db = buildSample(30);
  return db;
}

/// The frames of a baked EXR sequence (or any cache), frame-major.
inline std::vector<float> readBake(const std::string& pattern, const std::vector<int>& frames) {
  return readFrames(*openPointCache(pattern), frames);
}

/// One device (OpenCL or host) for a bake.
struct Backends {
  std::unique_ptr<Device> device;
  Device& view() const { return *device; }
};

inline Backends hostBackends() {
  return {makeHostDevice()};
}

/// A device that runs the projection, blend and layers on `stages` and every closest-point
/// search (binding, transfer, resolution, audit) on `closest`: compares one part of the
/// pipeline across devices with the rest held fixed. Both must outlive it.
class MixedDevice final : public Device {
 public:
  MixedDevice(Device& stages, Device& closest) : mStages(stages), mClosest(closest) {}
  std::string description() const override {
    return mStages.description() + " + " + mClosest.description();
  }
  bool isOpenCl() const override { return mStages.isOpenCl(); }
  std::unique_ptr<StageBackend> makeStages() override { return mStages.makeStages(); }
  std::unique_ptr<ClosestBackend> makeClosest(const ClosestOptions& options) override {
    return mClosest.makeClosest(options);
  }
  std::unique_ptr<LayerBackend> makeLayers() override { return mStages.makeLayers(); }
  std::unique_ptr<PositionMapBackend> makePositionMaps() override {
    return mStages.makePositionMaps();
  }
  std::unique_ptr<StrainLimitBackend> makeStrainLimit(int threads) override {
    return mStages.makeStrainLimit(threads);
  }

 private:
  Device& mStages;
  Device& mClosest;
};

/// Bake tests on the OpenCL device of OpenClTest (failing, never skipping, without one).
class BakeClTest : public OpenClTest {
 protected:
  Backends clBackends() { return {makeOpenClDevice(context(), device(), queue())}; }
};

}  // namespace drivenshape::testing
