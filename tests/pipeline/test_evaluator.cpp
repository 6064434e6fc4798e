// SPDX-License-Identifier: Apache-2.0
// The Evaluator against the command line's bake of the bundled sample: the same frames,
// bitwise, whatever the batch size or thread count; its temporal state; its device use.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <drivenshape/bake.h>
#include <drivenshape/database.h>
#include <drivenshape/device.h>
#include <drivenshape/device_cl.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluate.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/mesh.h>
#include <drivenshape/mesh_check.h>
#include <drivenshape/point_cache.h>

#include "cli_test_util.h"

namespace drivenshape {
namespace {

using testing::CliRun;
using testing::runCli;
using testing::sample;
using testing::TempDir;

/// The sample shot's frames (the test clip).
std::vector<int> shotFrames() {
  std::vector<int> frames;
  for (int f = 1; f <= 48; ++f) {
    frames.push_back(f);
  }
  return frames;
}

/// Frames [begin, begin + count) of a frame-major block of `values` floats per frame.
std::vector<float> slice(const std::vector<float>& block, std::size_t values, int begin,
                         int count) {
  return std::vector<float>(block.begin() + begin * values,
                            block.begin() + (begin + count) * values);
}

/// Number of floats of `a` and `b` whose bits differ.
int bitDifferences(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) {
    return -1;
  }
  int differences = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    differences += std::memcmp(&a[i], &b[i], sizeof(float)) != 0 ? 1 : 0;
  }
  return differences;
}

class EvaluatorTest : public testing::OpenClTest {
 protected:
  /// A 30-shape database of the sample, built by the CLI, and its bake of the test clip with
  /// the defaults on the OpenCL device (once per test binary).
  static void SetUpTestSuite() {
    testing::OpenClTest::SetUpTestSuite();
    sDir = new TempDir();
    const CliRun db =
        runCli(*sDir, {"db", "build", "--driver-mesh", sample("driver_rest.obj"), "--driven-mesh",
                       sample("driven_rest.obj"), "--driver", sample("train.driver.pc2"),
                       "--driven", sample("train.driven.pc2"), "--count", "30", "--quiet", "-o",
                       sDir->file("sleeve.dsdb")});
    ASSERT_EQ(db.code, 0) << db.err;
    const CliRun bake = runCli(*sDir, {"bake", "--db", sDir->file("sleeve.dsdb"), "--driver",
                                       sample("test.driver.pc2"), "--frames", "1-48", "--device",
                                       deviceSpec(), "--quiet", "-o", sDir->file("cli.####.exr")});
    ASSERT_EQ(bake.code, 0) << bake.err;
  }
  static void TearDownTestSuite() {
    delete sDir;
    sDir = nullptr;
  }

  static std::string file(const std::string& name) { return sDir->file(name); }

  static TempDir* sDir;
};

TempDir* EvaluatorTest::sDir = nullptr;

/// The shot evaluated `batch` frames per call (the last call takes what is left), each call's
/// Evaluation handed to `check` with its first index and count; returns the calls' cloth in
/// order. `vp` is the driver's floats per frame.
std::vector<float> inBatches(Evaluator& evaluator, const std::vector<int>& frames,
                             const std::vector<float>& driver, std::size_t vp, int batch,
                             const std::function<void(int, int, const Evaluation&)>& check) {
  std::vector<float> cloth;
  for (int begin = 0; begin < static_cast<int>(frames.size()); begin += batch) {
    const int count = std::min<int>(batch, static_cast<int>(frames.size()) - begin);
    const Evaluation out =
        evaluator.evaluate(std::vector<int>(frames.begin() + begin, frames.begin() + begin + count),
                           slice(driver, vp, begin, count));
    check(begin, count, out);
    cloth.insert(cloth.end(), out.cloth.begin(), out.cloth.end());
  }
  return cloth;
}

TEST_F(EvaluatorTest, MatchesTheCliBakeBitwiseForEveryBatchSizeAndThreadCount) {
  const Database db = loadDatabase(file("sleeve.dsdb"));
  const std::vector<int> frames = shotFrames();
  const std::vector<float> driver = readFrames(*openPointCache(sample("test.driver.pc2")), frames);
  const std::vector<float> cli = readFrames(*openPointCache(file("cli.####.exr")), frames);
  const std::size_t vp = 3 * static_cast<std::size_t>(db.driverVertexCount());
  const std::size_t vd = 3 * static_cast<std::size_t>(db.drivenVertexCount());
  std::unique_ptr<Device> device = makeOpenClDevice(context(), this->device(), queue());
  for (const int threads : {1, 2}) {
    EvaluatorSettings settings;
    settings.threads = threads;
    Evaluator evaluator(db, settings, *device);
    for (const int batch : {1, 7, 64}) {
      const std::vector<float> cloth = inBatches(
          evaluator, frames, driver, vp, batch, [&](int begin, int count, const Evaluation& out) {
            ASSERT_EQ(out.records.size(), static_cast<std::size_t>(count));
            EXPECT_EQ(out.records.front().frame, frames[begin]);
          });
      EXPECT_EQ(bitDifferences(cloth, cli), 0) << "batch " << batch << ", threads " << threads;
    }
  }
  ASSERT_EQ(cli.size(), frames.size() * vd);
}

TEST_F(EvaluatorTest, ClearanceCertificateGivesTheFullSearchsFramesBitwise) {
  // The train clip as the shot (its frames are 5 simulation frames apart: fast motion),
  // frames 1-10 and 50-60: with the certificate in one call, as two calls (the jump between
  // chunks) and in batches of 3, on 1 and 2 threads, on the host and OpenCL, against one call
  // with the full search. Defaults, a 2 cm skin offset (the resolution moves many vertices), and
  // that with world blending (the audit before the correction too).
  const Database db = loadDatabase(file("sleeve.dsdb"));
  std::vector<int> frames;
  for (int f = 1; f <= 10; ++f) {
    frames.push_back(f);
  }
  for (int f = 50; f <= 60; ++f) {
    frames.push_back(f);
  }
  const std::vector<float> driver = readFrames(*openPointCache(sample("train.driver.pc2")), frames);
  const std::size_t vp = 3 * static_cast<std::size_t>(db.driverVertexCount());
  const int count = static_cast<int>(frames.size());
  std::unique_ptr<Device> host = makeHostDevice();
  std::unique_ptr<Device> cl = makeOpenClDevice(context(), this->device(), queue());
  auto audits = [](const std::vector<FrameRecord>& records) {
    std::vector<int> out;
    for (const FrameRecord& r : records) {
      out.insert(out.end(), {r.insideBefore, r.insideCorrected, r.insideAfter, r.resolved});
    }
    return out;
  };
  for (Device* device : {host.get(), cl.get()}) {
    for (int variant = 0; variant < 3; ++variant) {
      EvaluatorSettings settings;
      settings.skinOffset = variant == 0 ? 0.002 : 0.02;
      settings.blend = variant == 2 ? BlendMode::kWorld : BlendMode::kLocal;
      const std::string what = device->description() + ", variant " + std::to_string(variant);
      EvaluatorSettings full = settings;
      full.clearanceCertificate = false;
      const Evaluation reference = Evaluator(db, full, *device).evaluate(frames, driver);
      long long resolved = 0;
      for (const FrameRecord& r : reference.records) {
        resolved += r.resolved;
        EXPECT_EQ(r.closestCleared, 0);
      }
      if (variant > 0) {
        EXPECT_GT(resolved, 0) << what;
      }
      for (const int threads : {1, 2}) {
        settings.threads = threads;
        for (const int batch : {count, 10, 3}) {
          Evaluator evaluator(db, settings, *device);
          std::vector<float> cloth;
          std::vector<FrameRecord> records;
          for (int begin = 0; begin < count; begin += batch) {
            const int n = std::min(batch, count - begin);
            const Evaluation out = evaluator.evaluate(
                std::vector<int>(frames.begin() + begin, frames.begin() + begin + n),
                slice(driver, vp, begin, n));
            cloth.insert(cloth.end(), out.cloth.begin(), out.cloth.end());
            records.insert(records.end(), out.records.begin(), out.records.end());
          }
          EXPECT_EQ(bitDifferences(cloth, reference.cloth), 0)
              << what << ", threads " << threads << ", batch " << batch;
          EXPECT_EQ(audits(records), audits(reference.records))
              << what << ", threads " << threads << ", batch " << batch;
          long long queries = 0;
          long long cleared = 0;
          for (const FrameRecord& r : records) {
            queries += r.closestQueries;
            cleared += r.closestCleared;
          }
          EXPECT_GT(cleared, 0) << what << ", threads " << threads << ", batch " << batch;
          EXPECT_LT(cleared, queries) << what;
        }
      }
    }
  }
}

TEST_F(EvaluatorTest, TemporalBoundCarriesAcrossCallsUntilReset) {
  // One frame per call, bound by the frame before, equals the bake that solves the same frames
  // in one batch; after resetTemporalBound() a frame is solved free again.
  const Database db = loadDatabase(file("sleeve.dsdb"));
  const std::vector<int> frames = shotFrames();
  const std::vector<float> driver = readFrames(*openPointCache(sample("test.driver.pc2")), frames);
  const std::size_t vp = 3 * static_cast<std::size_t>(db.driverVertexCount());
  std::unique_ptr<Device> host = makeHostDevice();

  BakeOptions options;
  options.frames = frames;
  options.evaluator.weightMode = WeightMode::kQp;  // the temporal bound is the QP's
  options.evaluator.maxWeightChange = 0.02;
  options.temporalWarmup = 0;
  options.batchFrames = 48;
  options.outputPattern = file("bounded.####.exr");
  const BakeResult bounded = bake(db, *openPointCache(sample("test.driver.pc2")), *host, options);

  EvaluatorSettings settings = evaluatorSettings(db, options);
  Evaluator evaluator(db, settings, *host);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const Evaluation out =
        evaluator.evaluate({frames[i]}, slice(driver, vp, static_cast<int>(i), 1));
    EXPECT_EQ(out.records[0].weights, bounded.frames[i].weights) << "frame " << frames[i];
  }
  // A free solve of frame 30 differs from the bounded one (the bound is active there), and a
  // reset gives exactly the free solve.
  EvaluatorSettings freeSettings = settings;
  freeSettings.maxWeightChange = 0.0;
  Evaluator unbounded(db, freeSettings, *host);
  const Evaluation free = unbounded.evaluate({30}, slice(driver, vp, 29, 1));
  ASSERT_NE(free.records[0].weights, bounded.frames[29].weights)
      << "the bound should be active at frame 30 with maxWeightChange 0.02";
  evaluator.resetTemporalBound();
  const Evaluation reset = evaluator.evaluate({30}, slice(driver, vp, 29, 1));
  EXPECT_EQ(reset.records[0].weights, free.records[0].weights);
}

TEST_F(EvaluatorTest, CompilesEachProgramOncePerDeviceAndCountsTransfers) {
  const Database db = loadDatabase(file("sleeve.dsdb"));
  const std::vector<float> driver =
      readFrames(*openPointCache(sample("test.driver.pc2")), {1, 2, 3});
  std::unique_ptr<Device> device = makeOpenClDevice(context(), this->device(), queue());
  Evaluator first(db, EvaluatorSettings(), *device);
  // Projection + blend, one closest-point program shared by the binding and the audit, and the
  // strain limit's (on by default).
  EXPECT_EQ(device->programsBuilt(), 3);
  Evaluator second(db, EvaluatorSettings(), *device);
  EXPECT_EQ(device->programsBuilt(), 3);
  const TransferCounts before = device->transfers();
  second.evaluate({1, 2, 3}, driver);
  const TransferCounts after = device->transfers();
  EXPECT_GT(after.uploads, before.uploads);
  EXPECT_GT(after.downloads, before.downloads);
  // At least the driver frames went in and the cloth came out.
  EXPECT_GE(after.uploadBytes - before.uploadBytes,
            static_cast<std::int64_t>(driver.size() * sizeof(float)));
  EXPECT_GE(after.downloadBytes - before.downloadBytes,
            static_cast<std::int64_t>(3 * 3 * db.drivenVertexCount() * sizeof(float)));
}

TEST_F(EvaluatorTest, KeepsABlockOnTheDeviceFromProjectionToTheLastKernel) {
  // After the first call (which also seeds the closest-point search from the host), a block
  // of F frames moves the driver in once per frame of reference it needs (world space for the
  // correction; with rigid alignment also the database's frame, which the host computes) and
  // the cloth out once; everything else is per-frame records.
  const Database db = loadDatabase(file("sleeve.dsdb"));
  const std::vector<int> frames = {1, 2, 3, 4, 5, 6, 7, 8};
  const std::vector<float> driver = readFrames(*openPointCache(sample("test.driver.pc2")), frames);
  const std::int64_t driverBytes = static_cast<std::int64_t>(driver.size() * sizeof(float));
  const std::int64_t clothBytes =
      static_cast<std::int64_t>(frames.size() * 3 * db.drivenVertexCount() * sizeof(float));
  // Records: projections, norms, weights and counters, far below one cloth frame per frame.
  const std::int64_t recordBytes = static_cast<std::int64_t>(frames.size()) * 1024;
  std::unique_ptr<Device> device = makeOpenClDevice(context(), this->device(), queue());
  for (const AlignMode align : {AlignMode::kRigid, AlignMode::kNone}) {
    EvaluatorSettings settings;
    settings.weightMode = WeightMode::kQp;  // the alignment is the QP's (the pose model has none)
    settings.align = align;
    Evaluator evaluator(db, settings, *device);
    evaluator.evaluate(frames, driver);
    const TransferCounts before = device->transfers();
    evaluator.evaluate(frames, driver);
    const TransferCounts after = device->transfers();
    const std::int64_t driverCopies = align == AlignMode::kRigid ? 2 : 1;
    EXPECT_GE(after.uploadBytes - before.uploadBytes, driverCopies * driverBytes);
    EXPECT_LE(after.uploadBytes - before.uploadBytes, driverCopies * driverBytes + recordBytes)
        << alignModeName(align);
    EXPECT_GE(after.downloadBytes - before.downloadBytes, clothBytes);
    EXPECT_LE(after.downloadBytes - before.downloadBytes, clothBytes + recordBytes)
        << alignModeName(align);
  }
}

/// The mean over `cloth`'s frames of each frame's mean |strain| against the database's rest
/// cloth.
double meanStrain(const Database& db, const std::vector<float>& cloth) {
  const std::vector<MeshEdge> edges = meshEdges(db.drivenMesh);
  const std::size_t values = 3 * static_cast<std::size_t>(db.drivenVertexCount());
  double sum = 0.0;
  for (std::size_t at = 0; at < cloth.size(); at += values) {
    sum += frameStrain(db.drivenMesh.positions.data(), cloth.data() + at, db.drivenVertexCount(),
                       edges)
               .mean;
  }
  return sum / static_cast<double>(cloth.size() / values);
}

// The strain limit (0.01 by default; 0.03 here) runs between the correction and the resolution:
// the cloth's strain falls against the bake without it, the resolution still leaves no vertex
// inside, the frames are the same bitwise on every batch size and thread count, and the host path
// agrees with the device.
TEST_F(EvaluatorTest, StrainLimitRunsBetweenTheCorrectionAndTheResolution) {
  const Database db = loadDatabase(file("sleeve.dsdb"));
  const std::vector<int> frames = shotFrames();
  const std::vector<float> driver = readFrames(*openPointCache(sample("test.driver.pc2")), frames);
  const std::size_t vp = 3 * static_cast<std::size_t>(db.driverVertexCount());
  std::unique_ptr<Device> device = makeOpenClDevice(context(), this->device(), queue());
  EvaluatorSettings settings;
  settings.strainLimit = 0.0;
  const std::vector<float> unlimitedCloth =
      Evaluator(db, settings, *device).evaluate(frames, driver).cloth;
  settings.strainLimit = 0.03;
  settings.strainIterations = 30;
  std::vector<float> reference;
  for (const int threads : {1, 2}) {
    settings.threads = threads;
    Evaluator evaluator(db, settings, *device);
    const std::vector<std::string> names = evaluator.stageNames();
    const auto at = [&](const char* name) {
      return std::find(names.begin(), names.end(), name) - names.begin();
    };
    EXPECT_EQ(at("strain"), at("correct") + 1);
    EXPECT_EQ(at("resolve"), at("strain") + 1);
    EXPECT_NE(evaluator.settingsHash(), Evaluator(db, EvaluatorSettings(), *device).settingsHash());
    for (const int batch : {1, 7, 48}) {
      const std::vector<float> cloth =
          inBatches(evaluator, frames, driver, vp, batch, [](int, int, const Evaluation& out) {
            for (const FrameRecord& record : out.records) {
              EXPECT_EQ(record.insideAfter, 0) << "frame " << record.frame;
            }
          });
      if (reference.empty()) {
        reference = cloth;
      }
      EXPECT_EQ(bitDifferences(cloth, reference), 0)
          << "batch " << batch << ", threads " << threads;
    }
  }
  const double limited = meanStrain(db, reference);
  const double unlimited = meanStrain(db, unlimitedCloth);
  std::printf("  mean |strain|: %.4f%% limited to 3%%, %.4f%% without\n", 100 * limited,
              100 * unlimited);
  EXPECT_LT(limited, 0.6 * unlimited);

  std::unique_ptr<Device> host = makeHostDevice();
  Evaluator onHost(db, settings, *host);
  const std::vector<float> hostCloth = onHost.evaluate(frames, driver).cloth;
  const double diagonal = boundsDiagonal(db.drivenMesh);
  double worst = 0.0;
  for (std::size_t i = 0; i < hostCloth.size(); i += 3) {
    double d2 = 0.0;
    for (std::size_t a = 0; a < 3; ++a) {
      d2 += (double(hostCloth[i + a]) - reference[i + a]) *
            (double(hostCloth[i + a]) - reference[i + a]);
    }
    worst = std::max(worst, std::sqrt(d2) / diagonal);
  }
  std::printf("  host vs OpenCL with the strain limit: %.3g of the diagonal\n", worst);
  EXPECT_LE(worst, testing::kDeviceVsHostRelTol + testing::kStrainLimitDeviceVsHostRelTol);
}

// The strain limit holds the garment's open borders (the sleeve's cuff and shoulder rings) where
// the pipeline put them and moves the rest: without the resolution (no skin planes), the limited
// bake's border vertices are the bytes of the bake without the limit on every frame, and most
// other vertices move.
TEST_F(EvaluatorTest, StrainLimitHoldsTheOpenBorders) {
  const Database db = loadDatabase(file("sleeve.dsdb"));
  const std::vector<int> frames = shotFrames();
  const std::vector<float> driver = readFrames(*openPointCache(sample("test.driver.pc2")), frames);
  const std::vector<int> border = borderVertices(db.drivenMesh);
  const MeshDefects defects = countMeshDefects(db.drivenMesh);
  // The sleeve is a tube: its two open rings have as many vertices as open edges.
  ASSERT_EQ(static_cast<int>(border.size()), defects.openEdges);
  ASSERT_GT(border.size(), 0u);
  std::unique_ptr<Device> device = makeOpenClDevice(context(), this->device(), queue());
  EvaluatorSettings settings;
  settings.resolve = false;
  settings.strainLimit = 0.0;
  const std::vector<float> plain = Evaluator(db, settings, *device).evaluate(frames, driver).cloth;
  settings.strainLimit = 0.01;
  const std::vector<float> limited =
      Evaluator(db, settings, *device).evaluate(frames, driver).cloth;
  ASSERT_EQ(plain.size(), limited.size());
  const int vd = db.drivenVertexCount();
  std::vector<bool> held(static_cast<std::size_t>(vd), false);
  for (const int v : border) {
    held[static_cast<std::size_t>(v)] = true;
  }
  int heldMoved = 0;
  int freeMoved = 0;
  for (std::size_t i = 0; i < plain.size(); i += 3) {
    const bool moved = std::memcmp(&plain[i], &limited[i], 3 * sizeof(float)) != 0;
    const auto v = static_cast<std::size_t>(i / 3) % static_cast<std::size_t>(vd);
    (held[v] ? heldMoved : freeMoved) += moved ? 1 : 0;
  }
  const std::size_t freePositions = frames.size() * (static_cast<std::size_t>(vd) - border.size());
  std::printf("  %zu border vertices held; %d of %zu other positions moved\n", border.size(),
              freeMoved, freePositions);
  EXPECT_EQ(heldMoved, 0);
  EXPECT_GT(freeMoved, static_cast<int>(freePositions / 2));
}

TEST_F(EvaluatorTest, MessagesNameSettingsAndTheFrameAtFault) {
  const Database db = loadDatabase(file("sleeve.dsdb"));
  std::unique_ptr<Device> host = makeHostDevice();
  EvaluatorSettings settings;
  settings.skinOffset = -1.0;
  testing::expectThrows([&] { Evaluator evaluator(db, settings, *host); }, ErrorCode::kUsage,
                        "skin offset");
  settings = EvaluatorSettings();
  settings.weightMode = WeightMode::kBind;
  settings.correct = false;
  testing::expectThrows([&] { Evaluator evaluator(db, settings, *host); }, ErrorCode::kUsage,
                        "correction off");

  Evaluator evaluator(db, EvaluatorSettings(), *host);
  std::vector<float> driver = readFrames(*openPointCache(sample("test.driver.pc2")), {5});
  driver[3 * 11 + 2] = std::numeric_limits<float>::infinity();
  testing::expectThrows([&] { evaluator.evaluate({5}, driver); }, ErrorCode::kInput,
                        "driver frame 5 vertex 11");
  testing::expectThrows([&] { evaluator.evaluate({5, 6}, driver); }, ErrorCode::kUsage, "2 frames");
}

}  // namespace
}  // namespace drivenshape
