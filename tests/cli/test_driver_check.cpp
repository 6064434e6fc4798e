// SPDX-License-Identifier: Apache-2.0
// The scale and correspondence checks of a shot's driver (drivenshape/driver_check.h) through
// the real command line: a driver in centimetres against a database in metres and a driver whose
// vertices do not correspond are refused with the cause named; --force bakes them with warnings;
// a 10% larger driver is warned about; the sample itself passes silently. The report's direct
// residual is checked against the same figure computed here from the database's shapes.

#include <cmath>
#include <filesystem>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <drivenshape/database.h>
#include <drivenshape/point_cache.h>

#include "cli_test_util.h"

namespace drivenshape {
namespace {

using testing::CliRun;
using testing::runCli;
using testing::sample;
using testing::TempDir;

/// Relative tolerance of the direct residual against the one computed here (both in double
/// from the same float shapes and weights; the weights pass through the report's decimal text).
constexpr double kResidualTol = 1e-6;

class DriverCheckTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new TempDir();
    sDb = testing::buildDb(*sDir);
    const auto cache = openPointCache(sample("test.driver.pc2"));
    sFrames = {1, 2, 3, 4, 5, 6, 7, 8};
    sDriver = readFrames(*cache, sFrames);
    sVertices = cache->vertexCount();
  }
  static void TearDownTestSuite() {
    delete sDir;
    sDir = nullptr;
  }

  /// Writes `xyz` (the sample frames, changed) as a PC2 starting at frame 1.
  static std::string writeDriver(const std::string& name, const std::vector<float>& xyz) {
    const std::string path = sDir->file(name);
    writePc2(path, sVertices, 1.0f, static_cast<int>(sFrames.size()), xyz.data());
    return path;
  }

  static CliRun bake(const std::string& driver, const std::string& name,
                     std::vector<std::string> extra = {}) {
    std::vector<std::string> args = {"bake",
                                     "--db",
                                     sDb,
                                     "--driver",
                                     driver,
                                     "--frames",
                                     "1-8",
                                     "--no-audit",
                                     "--device",
                                     "host",
                                     "--quiet",
                                     "-o",
                                     sDir->file(name + ".####.exr")};
    args.insert(args.end(), extra.begin(), extra.end());
    return runCli(*sDir, args);
  }

  static nlohmann::json report(const std::string& name) {
    return nlohmann::json::parse(testing::slurp(sDir->file(name + ".report.json")));
  }

  static TempDir* sDir;
  static std::string sDb;
  static std::vector<int> sFrames;
  static std::vector<float> sDriver;
  static int sVertices;
};

TempDir* DriverCheckTest::sDir = nullptr;
std::string DriverCheckTest::sDb;
std::vector<int> DriverCheckTest::sFrames;
std::vector<float> DriverCheckTest::sDriver;
int DriverCheckTest::sVertices = 0;

TEST_F(DriverCheckTest, CentimetresAgainstMetresAreRefusedWithTheCause) {
  std::vector<float> cm = sDriver;
  for (float& value : cm) {
    value *= 100.0f;
  }
  const std::string driver = writeDriver("cm.pc2", cm);
  const CliRun refused = bake(driver, "cm");
  testing::expectError(refused, 3, "100 times the database's size");
  EXPECT_NE(refused.err.find("centimetres against a database in metres"), std::string::npos)
      << refused.err;
  EXPECT_NE(refused.err.find("cm.pc2"), std::string::npos) << refused.err;
  EXPECT_FALSE(std::filesystem::exists(sDir->file("cm.0001.exr")));

  // Forced: baked, with the refusal and the poor fit as warnings (stderr and report).
  const CliRun forced = bake(driver, "cm", {"--force"});
  ASSERT_EQ(forced.code, 0) << forced.err;
  EXPECT_NE(forced.err.find("warning: forced:"), std::string::npos) << forced.err;
  const nlohmann::json json = report("cm");
  ASSERT_TRUE(json.contains("warnings"));
  EXPECT_GE(json["warnings"].size(), 2u);
  EXPECT_NE(json["warnings"].back().get<std::string>().find("fits the shot's driver poorly"),
            std::string::npos);
}

TEST_F(DriverCheckTest, VerticesThatDoNotCorrespondAreRefused) {
  // The same vertex count in another order: another character, as far as the database knows.
  std::vector<int> order(static_cast<std::size_t>(sVertices));
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  std::vector<float> shuffled(sDriver.size());
  for (std::size_t f = 0; f < sFrames.size(); ++f) {
    for (int v = 0; v < sVertices; ++v) {
      for (int c = 0; c < 3; ++c) {
        shuffled[(f * sVertices + v) * 3 + c] = sDriver[(f * sVertices + order[v]) * 3 + c];
      }
    }
  }
  testing::expectError(bake(writeDriver("shuffled.pc2", shuffled), "shuffled"), 3,
                       "the vertices do not correspond");
}

TEST_F(DriverCheckTest, ASlightlyLargerDriverIsWarnedAbout) {
  std::vector<float> larger = sDriver;
  for (float& value : larger) {
    value *= 1.1f;
  }
  const CliRun run = bake(writeDriver("larger.pc2", larger), "larger");
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.err.find("warning: "), std::string::npos);
  EXPECT_NE(run.err.find("scale 1.1"), std::string::npos) << run.err;
}

TEST_F(DriverCheckTest, TheSampleBakesWithoutWarningsAndItsDirectResidualIsExact) {
  // --align none: the fit is of the database's own driver shapes to the shot's frame, which
  // this test can compute from the database file and the report's weights.
  const CliRun run = bake(sample("test.driver.pc2"), "sample", {"--align", "none"});
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_EQ(run.err.find("warning"), std::string::npos) << run.err;
  const nlohmann::json json = report("sample");
  EXPECT_FALSE(json.contains("warnings"));
  const Database db = loadDatabase(sDb);
  const std::size_t values = 3 * static_cast<std::size_t>(sVertices);
  for (std::size_t f = 0; f < sFrames.size(); ++f) {
    const nlohmann::json& record = json["frames"][f];
    const std::vector<double> weights = record["weights"].get<std::vector<double>>();
    ASSERT_EQ(weights.size(), static_cast<std::size_t>(db.shapeCount()));
    double error2 = 0.0, norm2 = 0.0;
    for (std::size_t j = 0; j < values; ++j) {
      double fit = 0.0;
      for (int s = 0; s < db.shapeCount(); ++s) {
        fit += weights[s] * db.driverShapes[s * values + j];
      }
      const double b = sDriver[f * values + j];
      error2 += (fit - b) * (fit - b);
      norm2 += b * b;
    }
    const double expected = std::sqrt(error2 / norm2);
    const double reported = record["relative_residual_direct"].get<double>();
    EXPECT_NEAR(reported, expected, kResidualTol * expected) << "frame " << sFrames[f];
  }
}

}  // namespace
}  // namespace drivenshape
