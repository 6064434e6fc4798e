// SPDX-License-Identifier: Apache-2.0
// End-to-end bakes on the bundled sample shot (a slice of the sleeve scene): OpenCL against
// the host reference, the QP against the nearest-shape baseline, determinism, reports.

#include <drivenshape/bake.h>

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include <drivenshape/binding.h>
#include <drivenshape/database.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluate.h>

#include "bake_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using testing::Backends;
using testing::buildSample;
using testing::hostBackends;
using testing::readBake;
using testing::sample;
using testing::sampleDatabase;
using testing::TempDir;
using BakeTest = testing::BakeClTest;

/// Worst per-vertex distance between two baked sequences, as a fraction of each frame's
/// bounding-box diagonal; fails at the first vertex beyond kDeviceVsHostRelTol.
double compareBakes(const std::string& a, const std::string& b, const std::vector<int>& frames,
                    int vertexCount) {
  const std::size_t values = static_cast<std::size_t>(vertexCount) * 3;
  const std::vector<float> x = readBake(a, frames);
  const std::vector<float> y = readBake(b, frames);
  double worst = 0;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const Bounds bounds = computeBounds(&x[f * values], vertexCount);
    for (int v = 0; v < vertexCount; ++v) {
      const float* p = &x[f * values + 3 * v];
      const float* q = &y[f * values + 3 * v];
      const double d =
          std::sqrt(double(p[0] - q[0]) * (p[0] - q[0]) + double(p[1] - q[1]) * (p[1] - q[1]) +
                    double(p[2] - q[2]) * (p[2] - q[2]));
      worst = std::max(worst, d / bounds.diagonal());
      if (d > testing::kDeviceVsHostRelTol * bounds.diagonal()) {
        ADD_FAILURE() << "frame " << frames[f] << " vertex " << v << ": " << d / bounds.diagonal()
                      << " of the diagonal";
        return worst;
      }
    }
  }
  return worst;
}

// Each stage is compared with its host reference on identical inputs. (End to end with the
// correction on, the two paths may bind a vertex to different triangles where two triangles are
// equally close to within float rounding of the blended pose: the closest-triangle choice is
// discontinuous there, so inputs that differ in the last bit legitimately pick differently.)
TEST_F(BakeTest, OpenClBlendMatchesHostReferenceOnEveryFrame) {
  const Database& db = sampleDatabase();
  ASSERT_EQ(db.shapeCount(), 30);
  const auto driver = openPointCache(sample("test.driver.pc2"));
  TempDir dir;
  BakeOptions options;
  options.frames = driver->frames();
  options.batchFrames = 16;
  options.evaluator.correct = false;
  options.evaluator.strainLimit = 0.0;  // the blend alone (test_evaluator compares the limit)
  options.outputPattern = dir.file("host.####.exr");
  const Backends host = hostBackends();
  const BakeResult hostResult = bake(db, *driver, host.view(), options);
  options.outputPattern = dir.file("cl.####.exr");
  const Backends cl = clBackends();
  const BakeResult result = bake(db, *driver, cl.view(), options);
  EXPECT_EQ(result.baked, static_cast<int>(options.frames.size()));
  const double worst = compareBakes(dir.file("host.####.exr"), dir.file("cl.####.exr"),
                                    options.frames, db.drivenVertexCount());
  std::printf(
      "[ measured ] blend: worst OpenCL-vs-host distance %.3g of the diagonal (limit %.0e)\n",
      worst, testing::kDeviceVsHostRelTol);
}

TEST_F(BakeTest, OpenClCorrectionMatchesHostReferenceOnEveryFrame) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  TempDir dir;
  BakeOptions options;
  options.frames = driver->frames();
  options.batchFrames = 16;
  const Backends cl = clBackends();
  const Backends host = hostBackends();
  // Same blended inputs (OpenCL stages) for both; only the correction backends differ.
  options.outputPattern = dir.file("host.####.exr");
  testing::MixedDevice mixed(cl.view(), host.view());
  const BakeResult hostResult = bake(db, *driver, mixed, options);
  options.outputPattern = dir.file("cl.####.exr");
  const BakeResult result = bake(db, *driver, cl.view(), options);
  for (std::size_t f = 0; f < result.frames.size(); ++f) {
    EXPECT_EQ(result.frames[f].insideBefore, hostResult.frames[f].insideBefore) << f;
    EXPECT_EQ(result.frames[f].insideAfter, hostResult.frames[f].insideAfter) << f;
    EXPECT_EQ(result.frames[f].bindingSwitches, hostResult.frames[f].bindingSwitches) << f;
  }
  const double worst = compareBakes(dir.file("host.####.exr"), dir.file("cl.####.exr"),
                                    options.frames, db.drivenVertexCount());
  std::printf("[ measured ] correction: worst OpenCL-vs-host distance %.3g of the diagonal\n",
              worst);
}

TEST_F(BakeTest, CorrectionReducesPenetrationsAndErrorOnTheSample) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const auto truth = openPointCache(sample("test.driven.pc2"));
  TempDir dir;
  BakeOptions options;
  options.evaluator.blend = BlendMode::kWorld;  // the correction of the talk's world-space blend
  options.frames = driver->frames();
  const Backends cl = clBackends();
  options.outputPattern = dir.file("corrected.####.exr");
  const BakeResult corrected = bake(db, *driver, cl.view(), options);
  options.evaluator.correct = false;
  options.outputPattern = dir.file("blended.####.exr");
  bake(db, *driver, cl.view(), options);
  long before = 0, after = 0;
  for (const auto& record : corrected.frames) {
    before += record.insideBefore;
    after += record.insideAfter;
  }
  const auto withCorrection =
      evaluateCaches(*truth, *openPointCache(dir.file("corrected.####.exr")), options.frames);
  const auto without =
      evaluateCaches(*truth, *openPointCache(dir.file("blended.####.exr")), options.frames);
  std::printf(
      "[ measured ] inside the driver: %ld blended, %ld corrected; mean error %.5f "
      "corrected vs %.5f blended\n",
      before, after, withCorrection.mean, without.mean);
  EXPECT_LT(after, before);
  EXPECT_LE(withCorrection.mean, without.mean);
}

TEST_F(BakeTest, QpBeatsNearestShapeBaselineAgainstSimulatedTruth) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const auto truth = openPointCache(sample("test.driven.pc2"));
  TempDir dir;
  BakeOptions options;
  options.frames = driver->frames();
  const Backends cl = clBackends();
  options.evaluator.correct = false;  // compare the weights alone
  options.outputPattern = dir.file("qp.####.exr");
  bake(db, *driver, cl.view(), options);
  options.outputPattern = dir.file("nearest.####.exr");
  options.evaluator.weightMode = WeightMode::kNearest;
  bake(db, *driver, cl.view(), options);
  const auto qp = evaluateCaches(*truth, *openPointCache(dir.file("qp.####.exr")), options.frames);
  const auto nearest =
      evaluateCaches(*truth, *openPointCache(dir.file("nearest.####.exr")), options.frames);
  std::printf("[ measured ] mean error: qp %.5f, nearest %.5f; rms: qp %.5f, nearest %.5f\n",
              qp.mean, nearest.mean, qp.rms, nearest.rms);
  EXPECT_LT(qp.mean, nearest.mean);
  EXPECT_LT(qp.rms, nearest.rms);
}

TEST_F(BakeTest, DatabaseFramesReproduceTheirDrivenShape) {
  // Baking the database's own driver poses must give weight 1 on that shape and its driven
  // shape back: the reference data is the truth here. Without the strain limit, which brings the
  // simulation's own stretch (1-2%) into its 1% band and so moves the shape by a few mm.
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("train.driver.pc2"));
  TempDir dir;
  BakeOptions options;
  options.frames = {db.frames[0], db.frames[7], db.frames[29]};
  options.evaluator.strainLimit = 0.0;
  options.outputPattern = dir.file("db.####.exr");
  options.reportPath = dir.file("report.json");
  const Backends cl = clBackends();
  const BakeResult result = bake(db, *driver, cl.view(), options);
  const std::size_t values = db.drivenVertexCount() * 3;
  const std::vector<float> baked = readBake(options.outputPattern, options.frames);
  const int shapeIndex[] = {0, 7, 29};
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(result.frames[i].weights[shapeIndex[i]], 1.0, 1e-3)
        << "frame " << options.frames[i];
    const Bounds bounds =
        computeBounds(&db.drivenShapes[shapeIndex[i] * values], db.drivenVertexCount());
    double worst = 0;
    for (std::size_t j = 0; j < values; ++j) {
      worst = std::max(worst, std::abs(double(baked[i * values + j]) -
                                       db.drivenShapes[shapeIndex[i] * values + j]));
    }
    EXPECT_LE(worst, 1e-3 * bounds.diagonal()) << "frame " << options.frames[i];
  }
  // The report has one record per frame with the residual and active set.
  std::ifstream in(options.reportPath);
  const nlohmann::json report = nlohmann::json::parse(in);
  ASSERT_EQ(report.at("frames").size(), 3u);
  for (const auto& frame : report.at("frames")) {
    EXPECT_LT(frame.at("relative_residual").get<double>(), 1e-3);
    EXPECT_TRUE(frame.contains("active_at_zero"));
    double sum = 0;
    for (double w : frame.at("weights").get<std::vector<double>>()) {
      sum += w;
    }
    EXPECT_NEAR(sum, 1.0, 1e-6);
  }
}

TEST_F(BakeTest, OutputIsBitwiseIdenticalAcrossThreadsAndChunks) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  TempDir dir;
  const Backends cl = clBackends();
  BakeOptions options;
  options.frames = {1, 2, 3, 5, 8, 13, 21, 34};
  options.outputPattern = dir.file("a.####.exr");
  options.threads = 1;
  options.batchFrames = 8;
  bake(db, *driver, cl.view(), options);
  options.outputPattern = dir.file("b.####.exr");
  options.threads = 2;
  options.batchFrames = 3;
  bake(db, *driver, cl.view(), options);
  EXPECT_EQ(readBake(dir.file("a.####.exr"), options.frames),
            readBake(dir.file("b.####.exr"), options.frames));
}

}  // namespace
}  // namespace drivenshape
