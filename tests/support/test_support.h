#pragma once
// Shared by every test binary: tolerances (stated once per quantity), random seeds, temporary
// folders and the OpenCL fixture.

#include <gtest/gtest.h>

#include <CL/opencl.hpp>

#include <cstdint>
#include <random>
#include <string>

namespace drivenshape::testing {

// ---- Tolerances: one per quantity, used by every test that checks that quantity. ----

/// QP objective vs an independent solver, relative to the objective's scale ||b||^2.
inline constexpr double kQpObjectiveRelTol = 1e-9;
/// QP constraints: |sum(w) - 1| and bound violations.
inline constexpr double kQpConstraintTol = 1e-12;
/// OpenCL vs host reference: per-vertex distance, as a fraction of the bounding-box diagonal.
inline constexpr double kDeviceVsHostRelTol = 1e-5;
/// Float round trips through files (PC2, EXR FLOAT channels) must be exact.
inline constexpr float kFileRoundTripTol = 0.0f;

// ---- Random seeds: printed, overridable with DS_SEED=N. ----

/// The seed for this test: DS_SEED from the environment, else `fallback`. Printed once.
std::uint32_t testSeed(std::uint32_t fallback = 20081112u);

// ---- Files ----

/// Folder with the bundled test data (tests/data).
std::string dataDir();
/// A fresh empty folder under the build tree for the calling test, removed on destruction.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return mPath; }
  std::string file(const std::string& name) const { return mPath + "/" + name; }

 private:
  std::string mPath;
};

// ---- OpenCL ----

/// The OpenCL device all tests run on: the first device of the first platform (PoCL in CI),
/// or the one whose name contains DS_TEST_DEVICE. Created once per test binary and printed.
/// A missing device FAILS the test (CI must exercise the kernels), it never skips.
class OpenClTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite();
  void SetUp() override;
  static cl::Context& context();
  static cl::Device& device();
  static cl::CommandQueue& queue();
};

}  // namespace drivenshape::testing
