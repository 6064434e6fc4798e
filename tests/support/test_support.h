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
/// Projection stage, OpenCL vs host reference: |p_cl - p_host| per value, as a fraction of that
/// value's scale (||row|| * ||b - m|| for a projection by Cauchy-Schwarz, the value itself for
/// the norms, whose terms are all positive). The kernel sums products rounded to float with
/// Kahan compensation per work item, then adds 4 lanes and 64 items pairwise: a worst-case
/// bound of about 10 float roundings (10 * 2^-24 = 6e-7) of that scale, whatever the vertex
/// count. Measured: ~1.2e-7.
inline constexpr double kProjectionRelTol = 1e-6;
/// Host reference vs an independent double computation (Eigen), per value, as a fraction of
/// the value's scale as above (sum_i |w_i s_i| for a blend): the host sums in double and rounds
/// once to float, half an ulp (2^-24) plus double summation-order noise, so 2^-23.
inline constexpr double kHostVsDoubleRelTol = 1.0 / 8388608.0;
/// Float round trips through files (PC2, EXR FLOAT channels) must be exact.
inline constexpr float kFileRoundTripTol = 0.0f;
/// Position maps: |P_texel - P_expected| against an independent barycentric interpolation of
/// the triangle under the texel centre (computed in double), as a fraction of the bounding-box
/// diagonal of the frame (the acceptance bound of issue 6; float interpolation is ~1e-7).
inline constexpr double kPositionMapRelTol = 1e-5;
/// Unit normals of position maps: per-component difference between two computations of the
/// same normal (OpenCL vs host, float host vs an independent double computation). Float
/// cross-product sums and normalisation are good to ~1e-6 (measured 1.5e-6 on the sleeve);
/// interpolated normals that nearly cancel across sharp folds amplify that, hence the margin.
inline constexpr double kNormalTol = 1e-5;
/// Normals stored as HALF: at most one rounding of a value in [-1, 1], 2^-11 relative.
inline constexpr double kHalfNormalTol = 1.0 / 2048.0;
/// A padded texel repeats the arithmetic of the covered texel it copies on the same inputs, so
/// the two values are identical.
inline constexpr float kPaddingCopyTol = 0.0f;

// ---- Tolerances of the correction quantities (each used by every test of that quantity) ----

/// How far a hit's distance may be from the brute-force oracle's: relative * d + scale * S,
/// with d the oracle distance and S the scene scale (max of bounding-box diagonal and largest
/// coordinate magnitude).
struct DistanceTolerance {
  double relative;
  double scale;
};
/// Host backend and OpenCL devices computing in double: the stored distance2 is the double
/// result rounded to float (2^-24 relative to d^2, so 3e-8 of d), plus double rounding
/// (~1e-15 of S). A triangle missed by the candidate search shows as an error above this
/// unless it is within 1e-7 of d of the true minimum.
inline constexpr DistanceTolerance kClosestDistanceTol = {1e-7, 1e-9};
/// OpenCL forced to float arithmetic (ClosestOptions::forceSinglePrecision), on scenes without
/// needle-like slivers: a few float roundings of the scene scale.
inline constexpr DistanceTolerance kClosestSingleTol = {1e-5, 2e-6};
/// The distance to the hit's point q(u, v) vs the oracle, as a fraction of (S + d): u and v
/// are stored as float, so q moves by up to 2^-24 (|b - a| + |c - a|) <= 1.2e-7 S.
inline constexpr double kHitPointRelTol = 1e-6;
/// Transfer results vs their expected positions (identity, rigid motion), as a fraction of the
/// scene scale: float outputs of a double computation.
inline constexpr double kTransferRelTol = 1e-6;
/// Barycentric range of a hit: u >= -tol, v >= -tol, u + v <= 1 + tol (float rounding).
inline constexpr double kBarycentricTol = 1e-6;

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
