// End-to-end bakes on the bundled sample shot (a slice of the sleeve scene): OpenCL against
// the host reference, the QP against the nearest-shape baseline, determinism, reports.

#include <drivenshape/bake.h>

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include <drivenshape/cl_stages.h>
#include <drivenshape/database.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluate.h>

#include "test_support.h"

namespace drivenshape {
namespace {

using testing::TempDir;

std::string sample(const std::string& name) { return testing::dataDir() + "/sleeve/" + name; }

/// The 30-shape database of the sample, built once for the whole binary.
const Database& sampleDatabase() {
  static const Database db = [] {
    const Mesh driver = readObj(sample("driver_rest.obj"));
    const Mesh driven = readObj(sample("driven_rest.obj"));
    const auto driverCache = openPointCache(sample("train.driver.pc2"));
    const auto drivenCache = openPointCache(sample("train.driven.pc2"));
    DatabaseBuildOptions options;
    options.count = 30;
    return buildDatabase(driver, driven, *driverCache, *drivenCache, options);
  }();
  return db;
}

std::vector<float> readExrFrames(const std::string& pattern, const std::vector<int>& frames) {
  const auto cache = openPointCache(pattern);
  return readFrames(*cache, frames);
}

class BakeTest : public testing::OpenClTest {};

TEST_F(BakeTest, OpenClMatchesHostReferenceOnEveryFrame) {
  const Database& db = sampleDatabase();
  ASSERT_EQ(db.shapeCount(), 30);
  const auto driver = openPointCache(sample("test.driver.pc2"));
  TempDir dir;
  BakeOptions options;
  options.frames = driver->frames();
  options.chunkSize = 16;

  options.outputPattern = dir.file("host.####.exr");
  auto host = makeHostStages();
  bake(db, *driver, *host, options);
  options.outputPattern = dir.file("cl.####.exr");
  auto cl = makeClStages(context(), device(), queue());
  const BakeResult result = bake(db, *driver, *cl, options);
  EXPECT_EQ(result.baked, static_cast<int>(options.frames.size()));

  const std::size_t values = db.drivenVertexCount() * 3;
  const std::vector<float> a = readExrFrames(dir.file("host.####.exr"), options.frames);
  const std::vector<float> b = readExrFrames(dir.file("cl.####.exr"), options.frames);
  double worst = 0;
  for (std::size_t f = 0; f < options.frames.size(); ++f) {
    const Bounds bounds = computeBounds(&a[f * values], db.drivenVertexCount());
    const double limit = testing::kDeviceVsHostRelTol * bounds.diagonal();
    for (int v = 0; v < db.drivenVertexCount(); ++v) {
      const float* p = &a[f * values + 3 * v];
      const float* q = &b[f * values + 3 * v];
      const double d = std::sqrt(double(p[0] - q[0]) * (p[0] - q[0]) +
                                 double(p[1] - q[1]) * (p[1] - q[1]) +
                                 double(p[2] - q[2]) * (p[2] - q[2]));
      worst = std::max(worst, d / bounds.diagonal());
      ASSERT_LE(d, limit) << "frame " << options.frames[f] << " vertex " << v;
    }
  }
  std::printf("[ measured ] worst OpenCL-vs-host distance %.3g of the bbox diagonal (limit %.0e)\n",
              worst, testing::kDeviceVsHostRelTol);
}

TEST_F(BakeTest, QpBeatsNearestShapeBaselineAgainstSimulatedTruth) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const auto truth = openPointCache(sample("test.driven.pc2"));
  TempDir dir;
  BakeOptions options;
  options.frames = driver->frames();
  auto stages = makeClStages(context(), device(), queue());
  options.outputPattern = dir.file("qp.####.exr");
  bake(db, *driver, *stages, options);
  options.outputPattern = dir.file("nearest.####.exr");
  options.weightMode = WeightMode::kNearest;
  bake(db, *driver, *stages, options);
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
  // shape back: the reference data is the truth here.
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("train.driver.pc2"));
  TempDir dir;
  BakeOptions options;
  options.frames = {db.frames[0], db.frames[7], db.frames[29]};
  options.outputPattern = dir.file("db.####.exr");
  options.reportPath = dir.file("report.json");
  auto stages = makeClStages(context(), device(), queue());
  const BakeResult result = bake(db, *driver, *stages, options);
  const std::size_t values = db.drivenVertexCount() * 3;
  const std::vector<float> baked = readExrFrames(options.outputPattern, options.frames);
  const int shapeIndex[] = {0, 7, 29};
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(result.frames[i].weights[shapeIndex[i]], 1.0, 1e-3) << "frame " << options.frames[i];
    const Bounds bounds = computeBounds(&db.drivenShapes[shapeIndex[i] * values],
                                        db.drivenVertexCount());
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
  auto stages = makeClStages(context(), device(), queue());
  BakeOptions options;
  options.frames = {1, 2, 3, 5, 8, 13, 21, 34};
  options.outputPattern = dir.file("a.####.exr");
  options.threads = 1;
  options.chunkSize = 8;
  bake(db, *driver, *stages, options);
  options.outputPattern = dir.file("b.####.exr");
  options.threads = 2;
  options.chunkSize = 3;
  bake(db, *driver, *stages, options);
  EXPECT_EQ(readExrFrames(dir.file("a.####.exr"), options.frames),
            readExrFrames(dir.file("b.####.exr"), options.frames));
}

}  // namespace
}  // namespace drivenshape
