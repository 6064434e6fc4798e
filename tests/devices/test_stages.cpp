// SPDX-License-Identifier: Apache-2.0
// Per-frame stages: the host reference against Eigen in double, and the OpenCL kernels against
// the host reference (kernels/project.cl, kernels/blend.cl; src/devices/cl/cl_project.cpp,
// cl_blend.cpp and src/devices/host/host_project.cpp, host_blend.cpp).

#include <drivenshape/error.h>

#include "cl_backends.h"
#include "stages.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "cl_program.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using testing::kDeviceVsHostRelTol;
using testing::kHostVsDoubleRelTol;
using testing::kProjectionRelTol;
using testing::OpenClTest;
using testing::testSeed;

// ---- Synthetic data: positions like a garment 100 units from the origin, ~2 units across,
// ---- database shapes deviating by ~0.1 from a rest pose.

struct Problem {
  ShapeTables tables;
  int frameCount = 0;
  std::vector<float> driverFrames;  // F x 3Vp
  std::vector<float> weights;       // F x k
};

std::vector<float> restPose(int vertexCount, std::mt19937& rng) {
  std::uniform_real_distribution<float> box(100.0f, 102.0f);
  std::vector<float> rest(3 * static_cast<std::size_t>(vertexCount));
  for (float& x : rest) {
    x = box(rng);
  }
  return rest;
}

std::vector<float> shapesAround(const std::vector<float>& rest, int shapeCount, std::mt19937& rng) {
  std::normal_distribution<float> deviation(0.0f, 0.1f);
  std::vector<float> shapes;
  shapes.reserve(rest.size() * static_cast<std::size_t>(shapeCount));
  for (int i = 0; i < shapeCount; ++i) {
    for (float x : rest) {
      shapes.push_back(x + deviation(rng));
    }
  }
  return shapes;
}

// Weights on the simplex (what the QP produces), some of them exactly 0.
std::vector<float> simplexWeights(int frameCount, int shapeCount, std::mt19937& rng) {
  std::exponential_distribution<double> draw(1.0);
  std::bernoulli_distribution zero(0.3);
  std::vector<float> weights;
  for (int f = 0; f < frameCount; ++f) {
    std::vector<double> w(static_cast<std::size_t>(shapeCount));
    double sum = 0.0;
    for (double& x : w) {
      x = zero(rng) ? 0.0 : draw(rng);
      sum += x;
    }
    if (sum == 0.0) {
      w[static_cast<std::size_t>(f % shapeCount)] = sum = 1.0;
    }
    for (double x : w) {
      weights.push_back(static_cast<float>(x / sum));
    }
  }
  return weights;
}

// The tables the bake builds: center m = mean driver shape, M = A Z with Z an orthonormal
// basis of the plane sum(w) = 0 (columns 1..k-1 of the Householder Q of the ones vector).
Problem makeProblem(int driverVertices, int drivenVertices, int shapeCount, int frameCount,
                    std::uint32_t seed) {
  std::mt19937 rng(seed);
  Problem problem;
  ShapeTables& t = problem.tables;
  t.driverVertexCount = driverVertices;
  t.drivenVertexCount = drivenVertices;
  t.shapeCount = shapeCount;
  t.driverShapes = shapesAround(restPose(driverVertices, rng), shapeCount, rng);
  t.drivenShapes = shapesAround(restPose(drivenVertices, rng), shapeCount, rng);

  const Eigen::Index n = 3 * driverVertices;
  const Eigen::MatrixXd a =
      Eigen::Map<const Eigen::MatrixXf>(t.driverShapes.data(), n, shapeCount).cast<double>();
  const Eigen::VectorXd center = a.rowwise().mean();
  const Eigen::MatrixXd q = Eigen::VectorXd::Ones(shapeCount).householderQr().householderQ() *
                            Eigen::MatrixXd::Identity(shapeCount, shapeCount);
  const Eigen::MatrixXd basis = a * q.rightCols(shapeCount - 1);  // n x (k-1)
  t.center.resize(static_cast<std::size_t>(n));
  Eigen::Map<Eigen::VectorXf>(t.center.data(), n) = center.cast<float>();
  t.projectionRows.resize(static_cast<std::size_t>(n) * (shapeCount - 1));
  Eigen::Map<Eigen::MatrixXf>(t.projectionRows.data(), n, shapeCount - 1) = basis.cast<float>();

  // Driver frames near the span of the shapes, as a new pose of the same character is.
  problem.frameCount = frameCount;
  problem.weights = simplexWeights(frameCount, shapeCount, rng);
  std::normal_distribution<float> noise(0.0f, 0.02f);
  const std::vector<float> poseWeights = simplexWeights(frameCount, shapeCount, rng);
  problem.driverFrames.resize(static_cast<std::size_t>(frameCount) * n);
  for (int f = 0; f < frameCount; ++f) {
    for (Eigen::Index j = 0; j < n; ++j) {
      double x = 0.0;
      for (int i = 0; i < shapeCount; ++i) {
        x += poseWeights[static_cast<std::size_t>(f * shapeCount + i)] * a(j, i);
      }
      problem.driverFrames[static_cast<std::size_t>(f * n + j)] =
          static_cast<float>(x) + noise(rng);
    }
  }
  return problem;
}

// ---- Running a backend ----

struct ProjectResult {
  std::vector<float> projections;  // F x (k-1)
  std::vector<float> norms;        // F x 2
};

ProjectResult runProject(StageBackend& backend, const Problem& problem, int first, int count) {
  const std::size_t rows = static_cast<std::size_t>(problem.tables.shapeCount) - 1;
  const std::size_t n = 3 * static_cast<std::size_t>(problem.tables.driverVertexCount);
  ProjectResult result;
  result.projections.assign(static_cast<std::size_t>(count) * rows,
                            std::numeric_limits<float>::quiet_NaN());
  result.norms.assign(2 * static_cast<std::size_t>(count), std::numeric_limits<float>::quiet_NaN());
  backend.project(count, problem.driverFrames.data() + static_cast<std::size_t>(first) * n,
                  result.projections.data(), result.norms.data());
  return result;
}

struct BlendResult {
  std::vector<float> driven;  // F x 3Vd
  std::vector<float> driver;  // F x 3Vp, empty when not asked for
};

// Outputs get a NaN guard band past the chunk: a kernel writing past F frames shows up there.
constexpr std::size_t kGuardFloats = 64;

BlendResult runBlend(StageBackend& backend, const Problem& problem, int first, int count,
                     bool withDriver) {
  const std::size_t k = static_cast<std::size_t>(problem.tables.shapeCount);
  const std::size_t nd = 3 * static_cast<std::size_t>(problem.tables.drivenVertexCount);
  const std::size_t np = 3 * static_cast<std::size_t>(problem.tables.driverVertexCount);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  BlendResult result;
  result.driven.assign(static_cast<std::size_t>(count) * nd + kGuardFloats, nan);
  if (withDriver) {
    result.driver.assign(static_cast<std::size_t>(count) * np + kGuardFloats, nan);
  }
  backend.blend(count, problem.weights.data() + static_cast<std::size_t>(first) * k,
                result.driven.data(), withDriver ? result.driver.data() : nullptr);
  const auto guardIntact = [](const std::vector<float>& out) {
    return std::all_of(out.end() - kGuardFloats, out.end(), [](float x) { return std::isnan(x); });
  };
  EXPECT_TRUE(guardIntact(result.driven)) << "blend wrote past the driven frames of the chunk";
  result.driven.resize(result.driven.size() - kGuardFloats);
  if (withDriver) {
    EXPECT_TRUE(guardIntact(result.driver)) << "blend wrote past the driver frames of the chunk";
    result.driver.resize(result.driver.size() - kGuardFloats);
  }
  return result;
}

// ---- Comparisons ----

// Largest |got - want| / scale over the projections and norms of frames [first, first+count):
// scale = ||row r|| * ||b - m|| for projection r, the norm itself for the norms.
double projectionError(const Problem& problem, int first, int count, const ProjectResult& got,
                       const ProjectResult& want) {
  const ShapeTables& t = problem.tables;
  const std::size_t rows = static_cast<std::size_t>(t.shapeCount) - 1;
  const std::size_t n = 3 * static_cast<std::size_t>(t.driverVertexCount);
  std::vector<double> rowNorm(rows, 0.0);
  for (std::size_t r = 0; r < rows; ++r) {
    for (std::size_t j = 0; j < n; ++j) {
      rowNorm[r] += std::pow(static_cast<double>(t.projectionRows[r * n + j]), 2);
    }
    rowNorm[r] = std::sqrt(rowNorm[r]);
  }
  double worst = 0.0;
  for (std::size_t f = 0; f < static_cast<std::size_t>(count); ++f) {
    const float* b = problem.driverFrames.data() + (static_cast<std::size_t>(first) + f) * n;
    double dNorm = 0.0;
    for (std::size_t j = 0; j < n; ++j) {
      dNorm += std::pow(static_cast<double>(b[j]) - t.center[j], 2);
    }
    dNorm = std::sqrt(dNorm);
    for (std::size_t r = 0; r < rows; ++r) {
      const double error = std::abs(static_cast<double>(got.projections[f * rows + r]) -
                                    want.projections[f * rows + r]);
      worst = std::max(worst, std::isnan(error) ? 1e30 : error / (rowNorm[r] * dNorm));
    }
    for (std::size_t v = 0; v < 2; ++v) {
      const double reference = want.norms[2 * f + v];
      const double error = std::abs(static_cast<double>(got.norms[2 * f + v]) - reference);
      worst = std::max(worst, std::isnan(error) ? 1e30 : error / reference);
    }
  }
  return worst;
}

// Largest per-vertex distance between two blocks of frames, as a fraction of the bounding-box
// diagonal of the `want` frame it belongs to.
double positionError(const std::vector<float>& got, const std::vector<float>& want,
                     int vertexCount) {
  const std::size_t n = 3 * static_cast<std::size_t>(vertexCount);
  double worst = 0.0;
  for (std::size_t f = 0; f * n < want.size(); ++f) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = -lo;
    for (std::size_t v = 0; v < static_cast<std::size_t>(vertexCount); ++v) {
      const Eigen::Vector3d p =
          Eigen::Map<const Eigen::Vector3f>(want.data() + f * n + 3 * v).cast<double>();
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const double diagonal = (hi - lo).norm();
    for (std::size_t v = 0; v < static_cast<std::size_t>(vertexCount); ++v) {
      const Eigen::Vector3d a =
          Eigen::Map<const Eigen::Vector3f>(got.data() + f * n + 3 * v).cast<double>();
      const Eigen::Vector3d b =
          Eigen::Map<const Eigen::Vector3f>(want.data() + f * n + 3 * v).cast<double>();
      const double distance = (a - b).norm();
      worst = std::max(worst, std::isnan(distance) ? 1e30 : distance / diagonal);
    }
  }
  return worst;
}

void expectSameProjection(const Problem& problem, int first, int count, const ProjectResult& cl,
                          const ProjectResult& host) {
  const double error = projectionError(problem, first, count, cl, host);
  EXPECT_LE(error, kProjectionRelTol)
      << "projection, OpenCL vs host: measured " << error << " of scale, tolerance "
      << kProjectionRelTol << " (frames " << first << ".." << first + count - 1 << ")";
}

void expectSameBlend(const Problem& problem, int first, int count, const BlendResult& cl,
                     const BlendResult& host) {
  const double driven = positionError(cl.driven, host.driven, problem.tables.drivenVertexCount);
  EXPECT_LE(driven, kDeviceVsHostRelTol)
      << "blended driven, OpenCL vs host: measured " << driven << " of the bbox diagonal, "
      << "tolerance " << kDeviceVsHostRelTol << " (frames " << first << ".." << first + count - 1
      << ")";
  if (!host.driver.empty()) {
    const double driver = positionError(cl.driver, host.driver, problem.tables.driverVertexCount);
    EXPECT_LE(driver, kDeviceVsHostRelTol)
        << "blended driver, OpenCL vs host: measured " << driver << " of the bbox diagonal, "
        << "tolerance " << kDeviceVsHostRelTol;
  }
}

struct Size {
  int driverVertices;
  int drivenVertices;
  int shapeCount;
  int frameCount;
};

std::string describe(const Size& size) {
  return "Vp=" + std::to_string(size.driverVertices) +
         " Vd=" + std::to_string(size.drivenVertices) + " k=" + std::to_string(size.shapeCount) +
         " F=" + std::to_string(size.frameCount);
}

// 3V is never a multiple of 4 or 64 here (the padded paths), except in the last size, which
// takes the unpadded copies.
const std::vector<Size> kSizes = {
    {517, 250, 1, 7},   {1001, 1283, 2, 1},   {1283, 517, 30, 100}, {250, 1001, 64, 7},
    {517, 1283, 30, 1}, {1001, 250, 64, 100}, {1283, 1001, 2, 100}, {512, 1024, 30, 7},
};

// ---- Host reference vs Eigen in double ----

TEST(HostStages, MatchesEigenInDouble) {
  const std::uint32_t seed = testSeed();
  for (const Size& size : {Size{517, 250, 1, 7}, Size{250, 1001, 2, 7}, Size{1001, 517, 30, 7}}) {
    SCOPED_TRACE(describe(size));
    const Problem problem = makeProblem(size.driverVertices, size.drivenVertices, size.shapeCount,
                                        size.frameCount, seed);
    const ShapeTables& t = problem.tables;
    auto host = makeHostStages();
    EXPECT_EQ(host->name(), "host");
    host->upload(t);
    const ProjectResult projected = runProject(*host, problem, 0, size.frameCount);
    const BlendResult blended = runBlend(*host, problem, 0, size.frameCount, true);

    const Eigen::Index n = 3 * t.driverVertexCount;
    const Eigen::Index nd = 3 * t.drivenVertexCount;
    const Eigen::Index k = t.shapeCount;
    const Eigen::Index f = size.frameCount;
    using Rows = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const Eigen::MatrixXd m =
        Eigen::Map<const Rows>(t.projectionRows.data(), k - 1, n).cast<double>();
    const Eigen::VectorXd center =
        Eigen::Map<const Eigen::VectorXf>(t.center.data(), n).cast<double>();
    const Eigen::MatrixXd b =
        Eigen::Map<const Eigen::MatrixXf>(problem.driverFrames.data(), n, f).cast<double>();
    const Eigen::MatrixXd d = b.colwise() - center;
    const Eigen::MatrixXd p = m * d;  // (k-1) x F
    const Eigen::MatrixXd w =
        Eigen::Map<const Eigen::MatrixXf>(problem.weights.data(), k, f).cast<double>();
    const Eigen::MatrixXd drivenShapes =
        Eigen::Map<const Eigen::MatrixXf>(t.drivenShapes.data(), nd, k).cast<double>();
    const Eigen::MatrixXd driverShapes =
        Eigen::Map<const Eigen::MatrixXf>(t.driverShapes.data(), n, k).cast<double>();
    const Eigen::MatrixXd driven = drivenShapes * w;  // nd x F
    const Eigen::MatrixXd driver = driverShapes * w;

    double worst = 0.0;
    for (Eigen::Index frame = 0; frame < f; ++frame) {
      for (Eigen::Index r = 0; r < k - 1; ++r) {
        const double scale = m.row(r).norm() * d.col(frame).norm();
        worst = std::max(
            worst, std::abs(projected.projections[frame * (k - 1) + r] - p(r, frame)) / scale);
      }
      const double rr = d.col(frame).squaredNorm();
      const double bb = b.col(frame).squaredNorm();
      worst = std::max(worst, std::abs(projected.norms[2 * frame] - rr) / rr);
      worst = std::max(worst, std::abs(projected.norms[2 * frame + 1] - bb) / bb);
      const auto blendError = [&](const std::vector<float>& got, const Eigen::MatrixXd& want,
                                  const Eigen::MatrixXd& shapes) {
        const Eigen::VectorXd scale = shapes.cwiseAbs() * w.col(frame).cwiseAbs();
        for (Eigen::Index j = 0; j < want.rows(); ++j) {
          worst =
              std::max(worst, std::abs(got[frame * want.rows() + j] - want(j, frame)) / scale(j));
        }
      };
      blendError(blended.driven, driven, drivenShapes);
      blendError(blended.driver, driver, driverShapes);
    }
    EXPECT_LE(worst, kHostVsDoubleRelTol) << "host reference vs Eigen in double: measured " << worst
                                          << " of scale, tolerance " << kHostVsDoubleRelTol;
  }
}

TEST(HostStages, RefusesCallsBeforeUploadAndBadTables) {
  auto host = makeHostStages();
  float out[2];
  try {
    host->project(1, out, out, out);
    FAIL() << "project before upload must throw";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInternal);
    EXPECT_NE(std::string(error.what()).find("upload"), std::string::npos) << error.what();
  }
  ShapeTables bad = makeProblem(10, 10, 3, 1, 1).tables;
  bad.center.pop_back();
  try {
    host->upload(bad);
    FAIL() << "inconsistent tables must throw";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInternal);
    EXPECT_NE(std::string(error.what()).find("center"), std::string::npos) << error.what();
  }
}

// ---- OpenCL vs host ----

using ClStages = OpenClTest;

TEST_F(ClStages, NameIsTheDeviceName) {
  auto cl = makeClStages(context(), device(), queue());
  EXPECT_EQ(cl->name(), device().getInfo<CL_DEVICE_NAME>());
}

TEST_F(ClStages, ProjectAndBlendMatchHost) {
  const std::uint32_t seed = testSeed();
  auto cl = makeClStages(context(), device(), queue());
  auto host = makeHostStages();
  for (const Size& size : kSizes) {
    SCOPED_TRACE(describe(size));
    const Problem problem =
        makeProblem(size.driverVertices, size.drivenVertices, size.shapeCount, size.frameCount,
                    seed + static_cast<std::uint32_t>(size.shapeCount));
    cl->upload(problem.tables);  // re-uploading replaces the tables and the chunk layout
    host->upload(problem.tables);
    expectSameProjection(problem, 0, size.frameCount, runProject(*cl, problem, 0, size.frameCount),
                         runProject(*host, problem, 0, size.frameCount));
    const bool withDriver = size.frameCount != 1;
    expectSameBlend(problem, 0, size.frameCount,
                    runBlend(*cl, problem, 0, size.frameCount, withDriver),
                    runBlend(*host, problem, 0, size.frameCount, withDriver));
  }
}

TEST_F(ClStages, ChunkSizesGrowingAndShrinkingReuseBuffers) {
  const std::uint32_t seed = testSeed();
  const Problem problem = makeProblem(1283, 1001, 30, 250, seed);
  auto cl = makeClStages(context(), device(), queue());
  auto host = makeHostStages();
  cl->upload(problem.tables);
  host->upload(problem.tables);
  int first = 0;
  for (int count : {7, 100, 1, 33, 100, 2, 7}) {
    SCOPED_TRACE("chunk of " + std::to_string(count) + " frames from " + std::to_string(first));
    expectSameProjection(problem, first, count, runProject(*cl, problem, first, count),
                         runProject(*host, problem, first, count));
    expectSameBlend(problem, first, count, runBlend(*cl, problem, first, count, true),
                    runBlend(*host, problem, first, count, true));
    first += count;
  }
}

// The contract is any linear combination, not only the simplex the QP produces: weights that
// do not sum to 1 exercise the sum(w) - 1 term of blend.cl.
TEST_F(ClStages, BlendWithWeightsNotSummingToOne) {
  const std::uint32_t seed = testSeed();
  Problem problem = makeProblem(517, 1001, 30, 7, seed);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> any(-0.5f, 1.0f);
  for (float& w : problem.weights) {
    w = any(rng);
  }
  auto cl = makeClStages(context(), device(), queue());
  auto host = makeHostStages();
  cl->upload(problem.tables);
  host->upload(problem.tables);
  expectSameBlend(problem, 0, problem.frameCount, runBlend(*cl, problem, 0, 7, true),
                  runBlend(*host, problem, 0, 7, true));
}

// Regression: chunk buffers kept across upload() held the old tables' padded layout, so the
// zero padding of the driver frames sat in the wrong columns and projections came out wrong.
TEST_F(ClStages, ReuploadWithOtherVertexCountKeepsPaddingZero) {
  const std::uint32_t seed = testSeed();
  const Problem large = makeProblem(1283, 250, 30, 100, seed);
  const Problem small = makeProblem(1001, 250, 30, 7, seed + 1);
  auto cl = makeClStages(context(), device(), queue());
  auto host = makeHostStages();
  cl->upload(large.tables);
  runProject(*cl, large, 0, large.frameCount);
  cl->upload(small.tables);
  host->upload(small.tables);
  expectSameProjection(small, 0, small.frameCount, runProject(*cl, small, 0, small.frameCount),
                       runProject(*host, small, 0, small.frameCount));
}

TEST_F(ClStages, RefusesCallsBeforeUpload) {
  auto cl = makeClStages(context(), device(), queue());
  float out[2];
  try {
    cl->blend(1, out, out, nullptr);
    FAIL() << "blend before upload must throw";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInternal);
    EXPECT_NE(std::string(error.what()).find("upload"), std::string::npos) << error.what();
  }
}

// The one kernel source defined in a test: it exists to fail.
const cl_util::KernelSource kBrokenKernel = {
    "broken_on_purpose.cl",
    "__kernel void broken(__global float* out) { out[0] = no_such_variable_here; }\n"};

TEST_F(ClStages, BrokenKernelBuildThrowsDeviceErrorWithBuildLog) {
  try {
    cl_util::buildProgram(context(), device(), {kBrokenKernel});
    FAIL() << "a kernel that does not compile must throw";
  } catch (const Error& error) {
    const std::string message = error.what();
    EXPECT_EQ(error.code(), ErrorCode::kDevice);
    EXPECT_NE(message.find("broken_on_purpose.cl"), std::string::npos) << message;
    EXPECT_NE(message.find("CL_BUILD_PROGRAM_FAILURE"), std::string::npos) << message;
    EXPECT_NE(message.find("no_such_variable_here"), std::string::npos)
        << "the build log is missing from: " << message;
  }
}

TEST(ClErrors, StatusCodesHaveTheirNames) {
  EXPECT_STREQ(clErrorName(CL_OUT_OF_RESOURCES), "CL_OUT_OF_RESOURCES");
  EXPECT_STREQ(clErrorName(CL_INVALID_WORK_GROUP_SIZE), "CL_INVALID_WORK_GROUP_SIZE");
}

TEST(ClErrors, GuardTurnsClErrorIntoDeviceError) {
  try {
    cl_util::guard("reading back the projections",
                   []() -> int { throw cl::Error(CL_OUT_OF_RESOURCES, "clEnqueueReadBuffer"); });
    FAIL() << "guard must rethrow";
  } catch (const Error& error) {
    const std::string message = error.what();
    EXPECT_EQ(error.code(), ErrorCode::kDevice);
    EXPECT_NE(message.find("reading back the projections"), std::string::npos) << message;
    EXPECT_NE(message.find("clEnqueueReadBuffer"), std::string::npos) << message;
    EXPECT_NE(message.find("CL_OUT_OF_RESOURCES"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace drivenshape
