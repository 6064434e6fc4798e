// SPDX-License-Identifier: Apache-2.0
#pragma once
// Shared by every test binary: tolerances (stated once per quantity), random seeds, temporary
// folders, the check of a thrown drivenshape::Error and the OpenCL fixture.

#include <gtest/gtest.h>

#include <CL/opencl.hpp>

#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <drivenshape/database.h>
#include <drivenshape/error.h>

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
/// Penetration resolution: a moved point's distance to the driver vs the offset it was moved
/// to, as a fraction of the scene scale. The point q + offset N is a double computation
/// rounded to float (2^-24 of the coordinates, 6e-8 S per axis), and the closest point q
/// carries the float rounding of the stored (u, v) (kHitPointRelTol's 1.2e-7 S).
inline constexpr double kResolveRelTol = 1e-6;
/// Barycentric range of a hit: u >= -tol, v >= -tol, u + v <= 1 + tol (float rounding).
inline constexpr double kBarycentricTol = 1e-6;

// ---- Tolerances of `drivenshape eval` (tests/cli/test_eval.cpp) ----

/// Error and jump figures (mean, RMS, max distance) vs a brute-force double computation over
/// the same float positions: the sums differ only in their order, ~1e-16 relative per term.
inline constexpr double kEvalErrorRelTol = 1e-12;
/// Penetration depth vs the analytic depth inside a moved cube, as a fraction of the scene
/// scale S: float world positions (6e-8 of coordinates up to S) and the closest point's float
/// (u, v) (kHitPointRelTol's 1.2e-7 S) make a few 1e-7 S.
inline constexpr double kEvalDepthRelTol = 1e-6;
/// Edge strain (|edge| / |rest edge| - 1, eval's strain figures) of hand-made meshes vs its
/// closed form: float positions of coordinates up to ~10 (6e-8 relative each) make edge
/// lengths good to a few 1e-7 relative, and so the strains.
inline constexpr double kStrainTol = 1e-6;
/// Spearman rank correlation (eval --report) vs an independent computation from the same
/// values: ranks are exact halves, the sums differ only in their order (~1e-16 per term).
inline constexpr double kRankCorrelationTol = 1e-12;

// ---- Tolerances of the layer quantities (test_layers) ----

/// Mix of two positions w a + (1 - w) b in float vs the same formula in double, as a fraction
/// of max(|a|, |b|): two products, one difference and one sum, each rounded once (2^-24),
/// so 4 * 2^-24.
inline constexpr double kMixRelTol = 4.0 / 16777216.0;
/// Wind displacement, OpenCL vs the host reference, as a fraction of the wind amplitude. Both
/// run the same float operations (kernels/layer_types.h, FP_CONTRACT off); only sqrt, the
/// division and tanh of the clearance limit may differ by a few ulps (OpenCL allows 3-5 ulp),
/// so 1e-5 leaves a wide margin while an indexing or noise bug shows as errors of order 1.
/// Compared on positions, one ulp of the position the displacement is added to comes on top.
inline constexpr double kWindDeviceVsHostRelTol = 1e-5;
/// Float rounding of one wind displacement, as a fraction of the amplitude (a frame-to-frame
/// difference gets twice this on top of its analytic bound). The lattice coordinates stay below
/// 512 cells, where float rounds to 2^-16; through the noise slope (3.75 per axis, 3 axes) that
/// is 11.25 * 2^-16 = 1.7e-4 per channel, sqrt(3) of it for the vector: 3e-4. The ~30 roundings
/// of the lerps and octave sums (2e-6) are noise on top.
inline constexpr double kWindRoundingRelTol = 3e-4;

// ---- Tolerances of the strain limit (test_strain_limit) ----

/// The strain limit, OpenCL (float arithmetic, positions rounded to float every iteration) vs
/// the host reference (double, rounded once): per-vertex distance as a fraction of the
/// bounding-box diagonal, after up to 100 iterations. The iterations barely damp smooth errors,
/// so the float path's roundings add up: at most about one half-ulp of the coordinates per
/// iteration, 100 x 2^-24 x 2.4 = 1.4e-5 on the sleeve sample (which lies up to 2.4 diagonals
/// from the origin). Measured 3e-6 to 5.4e-6 over seeds at 100 iterations, 6e-7 at 10.
inline constexpr double kStrainLimitDeviceVsHostRelTol = 2e-5;

// ---- Tolerances of the fidelity stages (issue 4) ----

/// Rigid alignment recovering a known motion of float positions: entries of R and t/S (S the
/// bounding-box diagonal) vs the truth. Inputs carry float rounding (6e-8 of the coordinates,
/// which sit up to several S from the origin once moved); a well-spread selection keeps the
/// fit's conditioning near 1, so 1e-5 leaves two orders of margin.
inline constexpr double kAlignTol = 1e-5;
/// Rigidity-weighted fit (RigidAligner::weightByRigidity, default options) of a rigid part
/// while the rest of the mesh bends by 10-100 degrees, as the worst distance of the aligned
/// rigid part from its rest (fraction of the diagonal). The bending vertices keep a robust
/// weight area tau^2 / (r^2 + tau^2) (tau = 0.01 of the diagonal): a bias of order tau^2 that
/// the vertices next to the joint (small r) dominate, 2.6e-3 measured; 5e-3 keeps 2x margin
/// while the plain area fit is off by 0.13.
inline constexpr double kRigidityAlignTol = 5e-3;
/// World-space invariance of a whole bake: the acceptance bound of issue 4, as a fraction of
/// the bounding-box diagonal of the frame.
inline constexpr double kWorldInvarianceRelTol = 1e-4;
/// Region falloff: |sum_r phi_r - 1| per vertex; each phi is a double quotient rounded once to
/// float (2^-24), summed over a handful of regions.
inline constexpr double kPartitionOfUnityTol = 1e-6;
/// Temporal bound |w_t - w_{t-1}| <= tau: the QP keeps bounds exactly up to double rounding of
/// the box edges (prev +- tau).
inline constexpr double kWeightBoundTol = 1e-12;

/// A driven mesh offset from its driver along the driver's area-weighted vertex normals (a
/// muscle 5 mm under the sleeve's skin, tests/database_build/test_bake_sides.cpp): mean
/// distance of the bake of another clip from the offset truth, in scene units (metres).
/// Measured 0.033 mm with the defaults and with the resolution off; 0.1 mm keeps 3x margin,
/// while a resolution that pushes the muscle out to the skin offset (2 mm outside) is off by
/// about 7 mm.
inline constexpr double kInsetMeanErrorTol = 1e-4;

/// The pose model's posterior deviation after added observations (db build --suggest): rank-one
/// updates vs a direct inversion of the grown kernel matrix, both in double, relative to the
/// deviation. The kernel matrix carries the ridge (>= 0.03) on its diagonal, so its condition
/// number stays below about 1e4 and both routes agree to ~1e-12; 1e-9 leaves the margin.
inline constexpr double kPosteriorRelTol = 1e-9;

// ---- Random seeds: printed, overridable with DS_SEED=N. ----

/// The seed for this test: DS_SEED from the environment, else `fallback`. Printed once.
std::uint32_t testSeed(std::uint32_t fallback = 20081112u);

// ---- Files ----

/// Folder with the bundled test data (tests/data).
std::string dataDir();
/// A `count`-shape database of the bundled sleeve sample (tests/data/sleeve), built in process
/// from its `train` clip, with or without the pose model.
Database buildSleeveDatabase(bool poseModel, int count = 10);

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

// ---- Errors ----

/// Runs `call` and expects it to throw a drivenshape::Error with `code` whose message contains
/// `fragment`; a test failure (with the message) otherwise, also when nothing is thrown.
void expectThrows(const std::function<void()>& call, ErrorCode code, const std::string& fragment);

/// The frame numbers first, first + 1, ..., last (empty when last < first).
std::vector<int> frameRange(int first, int last);

/// Mean per-vertex distance between two blocks of frames of interleaved xyz (scene units): the
/// mean vertex error of `a` against `b`.
double meanVertexDistance(const std::vector<float>& a, const std::vector<float>& b);

// ---- Rank correlation, computed apart from src/shot/coverage_check.cpp ----

/// Average ranks by counting (O(n^2), no sorting): 1 + the values below + half the other values
/// equal to it, i.e. the mean of the positions its tie group occupies.
std::vector<double> countedRanks(const std::vector<double>& v);

/// Pearson's correlation with the means taken from the values (two passes). NaN when a side is
/// constant.
double referencePearson(const std::vector<double>& x, const std::vector<double>& y);

/// Spearman's rank correlation: referencePearson of the countedRanks.
double referenceSpearman(const std::vector<double>& x, const std::vector<double>& y);

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
  /// The device's name, as `--device` takes it, for tests that run the CLI beside the device;
  /// "cpu" when there is none (the CLI's error then names it).
  static std::string deviceSpec();
};

}  // namespace drivenshape::testing
