// SPDX-License-Identifier: Apache-2.0
// Several reference clips for the pose model (issue 17, `db build --also`): a clip split in two
// fits the model of the whole, velocity and history never read another clip, clips of another
// mesh are refused by name, and a second clip lowers the error on its motion.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <vector>

#include <drivenshape/database.h>
#include <drivenshape/database_build.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/pose_model.h>

#include "bake_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using testing::sample;

/// The sample's train clip (candidates `frames`, empty = all) plus extra clips of the sample's
/// caches: {driver cache, driven cache, frames}.
struct ClipSpec {
  std::string driver, driven;
  std::vector<int> frames;
};
Database buildWithClips(const std::vector<int>& frames, const std::vector<ClipSpec>& extra,
                        bool poseModel = true, int historyFrames = kAutoHistory) {
  const Mesh driver = readObj(sample("driver_rest.obj"));
  const Mesh driven = readObj(sample("driven_rest.obj"));
  const auto driverCache = openPointCache(sample("train.driver.pc2"));
  const auto drivenCache = openPointCache(sample("train.driven.pc2"));
  std::vector<std::unique_ptr<PointCacheReader>> caches;
  std::vector<ReferenceClip> clips;
  for (const ClipSpec& spec : extra) {
    caches.push_back(openPointCache(sample(spec.driver)));
    caches.push_back(openPointCache(sample(spec.driven)));
    clips.push_back({caches[caches.size() - 2].get(), caches.back().get(), spec.frames});
  }
  DatabaseBuildOptions options;
  options.frames = frames;
  options.poseModel = poseModel;
  options.model.historyFrames = historyFrames;
  return buildDatabase(driver, driven, *driverCache, *drivenCache, clips, options);
}

TEST(ReferenceClips, AClipSplitInTwoFitsTheModelOfTheWholeClip) {
  // The train clip as one clip, and as frames 1-30 plus a second clip of frames 31-61 of the
  // same caches: the second clip's history reads frames 17-30 of its own cache, so every
  // feature, target and fold is the same and so is the model (with the history given: by
  // default two clips read a longer one, see below).
  const Database whole = buildWithClips({}, {}, true, 15);
  const Database split = buildWithClips(
      testing::frameRange(1, 30),
      {{"train.driver.pc2", "train.driven.pc2", testing::frameRange(31, 61)}}, true, 15);
  const PoseModel& a = whole.poseModel;
  const PoseModel& b = split.poseModel;
  ASSERT_EQ(a.frameCount(), 61);
  ASSERT_EQ(b.frameCount(), 61);
  ASSERT_EQ(split.extraClips.size(), 1u);
  const ReferenceClipSource& clip = split.extraClips[0];
  EXPECT_EQ(clip.driverSource, sample("train.driver.pc2"));
  EXPECT_EQ(clip.drivenSource, sample("train.driven.pc2"));
  EXPECT_EQ(clip.frames, testing::frameRange(31, 61));
  EXPECT_EQ(clip.frameOffset, 100000) << "the smallest positive multiple of 100000";
  for (int i = 0; i < 61; ++i) {
    EXPECT_EQ(b.frames[i], a.frames[i] + (i < 30 ? 0 : clip.frameOffset)) << "row " << i;
  }
  EXPECT_EQ(a.partOf, b.partOf);
  EXPECT_EQ(a.features, b.features) << "the split changes no feature";
  EXPECT_EQ(a.lengthScale, b.lengthScale);
  EXPECT_EQ(a.linearWeight, b.linearWeight);
  EXPECT_EQ(a.ridge, b.ridge);
  EXPECT_EQ(a.coefficients, b.coefficients);
  EXPECT_EQ(a.crossValidationError, b.crossValidationError)
      << "a fold boundary at the clip boundary changes nothing";
}

// The history's default follows the reference data: 15 frames with one or two clips, 30 with
// three or more (historyFramesFor); a history given is kept either way.
TEST(ReferenceClips, TheDefaultHistoryIsLongerWithThreeClips) {
  const std::vector<ClipSpec> second = {
      {"train.driver.pc2", "train.driven.pc2", testing::frameRange(31, 61)}};
  const std::vector<ClipSpec> secondAndThird = {
      {"train.driver.pc2", "train.driven.pc2", testing::frameRange(21, 40)},
      {"train.driver.pc2", "train.driven.pc2", testing::frameRange(41, 61)}};
  EXPECT_EQ(buildWithClips({}, {}).poseModel.historyFrames, 15);
  EXPECT_EQ(buildWithClips(testing::frameRange(1, 30), second).poseModel.historyFrames, 15);
  EXPECT_EQ(buildWithClips(testing::frameRange(1, 20), secondAndThird).poseModel.historyFrames, 30);
  EXPECT_EQ(
      buildWithClips(testing::frameRange(1, 20), secondAndThird, true, 15).poseModel.historyFrames,
      15);
  EXPECT_EQ(buildWithClips({}, {}, true, 0).poseModel.historyFrames, 0);
}

/// docs/method.md's features, by hand: pose features p of a cache's frames 1.. (row f - 1),
/// velocity p[f] - p[f - lag], history p[f] - mean of p[f - j] for j < H, a frame before the
/// cache's first standing in with the first.
std::vector<double> handFeatures(const PoseModel& m, const std::vector<std::vector<double>>& p,
                                 int f) {
  const auto at = [&](int frame) { return p[static_cast<std::size_t>(std::max(1, frame) - 1)]; };
  const std::vector<double>& now = at(f);
  std::vector<double> out = now;
  for (std::size_t c = 0; c < now.size(); ++c) {
    out.push_back(now[c] - at(f - m.velocityLag)[c]);
  }
  for (std::size_t c = 0; c < now.size(); ++c) {
    double sum = 0.0;
    for (int j = 0; j < m.historyFrames; ++j) {
      sum += at(f - j)[c];
    }
    out.push_back(now[c] - sum / m.historyFrames);
  }
  return out;
}

TEST(ReferenceClips, VelocityAndHistoryNeverReadAnotherClip) {
  // Main: train frames 1-30. Clip 2: frames 31-48 of the test clip, whose numbers continue the
  // main clip's (without renumbering, its frame 31 would read train frame 30 as its past); its
  // history is the test clip's frames 17-30. Clip 3: test frames 1-10, the same numbers as the
  // main clip's first frames, with no earlier frames at all.
  const Database db =
      buildWithClips(testing::frameRange(1, 30),
                     {{"test.driver.pc2", "test.driven.pc2", testing::frameRange(31, 48)},
                      {"test.driver.pc2", "test.driven.pc2", testing::frameRange(1, 10)}});
  const PoseModel& m = db.poseModel;
  ASSERT_EQ(m.frameCount(), 30 + 18 + 10);
  ASSERT_GT(m.velocityLag, 0);
  ASSERT_GT(m.historyFrames, 1);
  const PosePredictor predictor(m, db.driverMesh);
  const auto poseOf = [&](const std::string& name) {
    const auto cache = openPointCache(sample(name));
    const std::vector<int> frames = cache->frames();
    const std::vector<float> xyz = readFrames(*cache, frames);
    std::vector<std::vector<double>> p(frames.size(), std::vector<double>(m.poseFeatureCount()));
    for (std::size_t f = 0; f < frames.size(); ++f) {
      EXPECT_EQ(frames[f], static_cast<int>(f) + 1);
      predictor.poseFeatures(&xyz[f * db.driverVertexCount() * 3], p[f].data());
    }
    return p;
  };
  const std::vector<std::vector<double>> train = poseOf("train.driver.pc2");
  const std::vector<std::vector<double>> test = poseOf("test.driver.pc2");
  struct Row {
    const std::vector<std::vector<double>>* pose;
    int frame;
  };
  std::vector<Row> rows;
  for (int f = 1; f <= 30; ++f) {
    rows.push_back({&train, f});
  }
  for (int f = 31; f <= 48; ++f) {
    rows.push_back({&test, f});
  }
  for (int f = 1; f <= 10; ++f) {
    rows.push_back({&test, f});
  }
  const int d = m.featureCount();
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const std::vector<double> expected = handFeatures(m, *rows[r].pose, rows[r].frame);
    ASSERT_EQ(static_cast<int>(expected.size()), d);
    double scale = 0.0;
    for (const std::vector<double>& p : *rows[r].pose) {
      for (double v : p) {
        scale = std::max(scale, std::abs(v));
      }
    }
    for (int c = 0; c < d; ++c) {
      const double stored = m.features[r * d + c];
      ASSERT_NEAR(stored, expected[c],
                  testing::kHostVsDoubleRelTol * (scale + std::abs(expected[c])))
          << "model row " << r << " (clip frame " << rows[r].frame << "), feature " << c;
    }
  }
  // The clips' model frame numbers lie apart by more than the history.
  ASSERT_EQ(db.extraClips.size(), 2u);
  EXPECT_GT(db.extraClips[0].frameOffset + 17, 30 + m.historyNeeded() + 1);
  EXPECT_GT(db.extraClips[1].frameOffset + 1,
            db.extraClips[0].frameOffset + 48 + m.historyNeeded() + 1);
}

TEST(ReferenceClips, ClipsOfAnotherMeshOrWithoutTheirFramesAreRefusedByName) {
  testing::expectThrows(
      [] {
        buildWithClips({}, {{"test.driven.pc2", "test.driven.pc2", {}}});
      },
      ErrorCode::kInput,
      "reference clip 2: driver cache '" + sample("test.driven.pc2") + "' has 2244 vertices");
  testing::expectThrows(
      [] {
        buildWithClips({}, {{"test.driver.pc2", "test.driven.pc2", {}},
                            {"test.driver.pc2", "test.driver.pc2", {}}});
      },
      ErrorCode::kInput,
      "reference clip 3: driven cache '" + sample("test.driver.pc2") + "' has 2146 vertices");
  testing::expectThrows(
      [] {
        buildWithClips({}, {{"test.driver.pc2", "test.driven.pc2", testing::frameRange(40, 50)}});
      },
      ErrorCode::kInput,
      "reference clip 2: cache '" + sample("test.driver.pc2") + "' has no frame 49");
  testing::expectThrows(
      [] {
        buildWithClips({}, {{"test.driver.pc2", "test.driven.pc2", {}}}, false);
      },
      ErrorCode::kUsage, "pose model");
}

TEST(ReferenceClips, ASecondClipLowersTheErrorOnItsMotion) {
  // The test clip's first half as a second clip; its second half (held out) is the shot.
  const Database one = buildWithClips({}, {});
  const Database two =
      buildWithClips({}, {{"test.driver.pc2", "test.driven.pc2", testing::frameRange(1, 24)}});
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const auto truth = openPointCache(sample("test.driven.pc2"));
  const std::vector<int> frames = testing::frameRange(1, 48);
  const std::vector<float> pose = readFrames(*driver, frames);
  const std::vector<float> expected = readFrames(*truth, testing::frameRange(25, 48));
  testing::Backends host = testing::hostBackends();
  EvaluatorSettings settings;
  settings.resolve = false;
  const auto heldOut = [&](const Database& db, double& predicted) {
    const Evaluation e = Evaluator(db, settings, host.view()).evaluate(frames, pose);
    const std::size_t dd = static_cast<std::size_t>(db.drivenVertexCount()) * 3;
    predicted = 0.0;
    for (int f = 24; f < 48; ++f) {
      predicted += e.records[f].predictedError / 24.0;
    }
    return testing::meanVertexDistance(std::vector<float>(e.cloth.begin() + 24 * dd, e.cloth.end()),
                                       expected);
  };
  double predictedOne = 0.0, predictedTwo = 0.0;
  const double errorOne = heldOut(one, predictedOne);
  const double errorTwo = heldOut(two, predictedTwo);
  std::cout << "held-out test frames 25-48, mean vertex error (predicted): train clip " << errorOne
            << " (" << predictedOne << "), train + test 1-24 " << errorTwo << " (" << predictedTwo
            << ")\n";
  EXPECT_LT(errorTwo, errorOne);
}

}  // namespace
}  // namespace drivenshape
