// SPDX-License-Identifier: Apache-2.0
// The shot planner (drivenshape/shot_plan.h) against brute-force expectations written from what
// the plan is for, not from how it is computed: every output frame must see, walking back
// through the frames its call evaluates before it, exactly the history a whole bake gives it
// (the consecutive earlier frames the source holds, up to the history length), and with the
// temporal bound the same chain of frames solved since the bound's restart as the whole bake of
// the same frames.

#include <drivenshape/shot_plan.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>

#include "bake_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using testing::buildSample;
using testing::hostBackends;
using testing::sampleDatabase;

/// The frames a whole bake lets `frame` read as history: frame - 1, frame - 2, ... while the
/// source holds them, at most `history` (a frame the source lacks ends the walk).
std::vector<int> idealHistory(int frame, const std::set<int>& source, int history) {
  std::vector<int> out;
  for (long long f = static_cast<long long>(frame) - 1;
       static_cast<int>(out.size()) < history && source.count(static_cast<int>(f)) > 0; --f) {
    out.push_back(static_cast<int>(f));
  }
  return out;
}

/// The history the evaluator reads for solve[p]: walking back through consecutive frame
/// numbers among the frames evaluated before it in the same call (PosePredictor::features).
std::vector<int> walkedHistory(const std::vector<int>& solve, std::size_t p, int history) {
  std::vector<int> out;
  for (std::size_t q = p; q > 0 && static_cast<int>(out.size()) < history; --q) {
    if (static_cast<long long>(solve[q - 1]) + 1 != solve[q]) {
      break;
    }
    out.push_back(solve[q - 1]);
  }
  return out;
}

/// The source's frames in [first - count, first), by scanning every frame it holds.
std::vector<int> framesBeforeByScan(const std::set<int>& source, int first, int count) {
  std::vector<int> out;
  for (int f : source) {
    if (static_cast<long long>(f) >= static_cast<long long>(first) - count && f < first) {
      out.push_back(f);
    }
  }
  return out;
}

std::string describe(const std::vector<int>& frames) {
  std::string text;
  for (int f : frames) {
    text += (text.empty() ? "" : ",") + std::to_string(f);
  }
  return "[" + text + "]";
}

/// A random source (frames 0-59 with a few holes) and random frames to bake from it: runs of
/// consecutive frames, jumps back and forth, repeats.
struct RandomShot {
  std::set<int> source;
  std::vector<int> frames;
};

RandomShot randomShot(std::mt19937& random) {
  RandomShot shot;
  for (int f = 0; f < 60; ++f) {
    if (random() % 9 != 0) {
      shot.source.insert(f);
    }
  }
  const std::vector<int> held(shot.source.begin(), shot.source.end());
  int frame = held[random() % held.size()];
  const int count = 1 + static_cast<int>(random() % 40);
  for (int i = 0; i < count; ++i) {
    shot.frames.push_back(frame);
    const unsigned kind = random() % 10;
    const int next = kind < 6 ? frame + 1 : kind < 8 ? held[random() % held.size()] : frame - 1;
    frame = shot.source.count(next) > 0 ? next : held[random() % held.size()];
  }
  return shot;
}

TEST(ShotPlan, EveryFrameSeesTheHistoryOfTheWholeBake) {
  const unsigned seed = testing::testSeed();
  std::mt19937 random(seed);
  for (int trial = 0; trial < 400; ++trial) {
    const RandomShot shot = randomShot(random);
    ShotPlanSettings settings;
    settings.batch = 1 + static_cast<int>(random() % 9);
    settings.historyFrames = 1 + static_cast<int>(random() % 15);
    const std::vector<int> available(shot.source.rbegin(), shot.source.rend());  // any order
    const std::vector<BatchPlan> plan = planShot(shot.frames, available, settings);
    SCOPED_TRACE("seed " + std::to_string(seed) + ", trial " + std::to_string(trial) + ": frames " +
                 describe(shot.frames) + ", batch " + std::to_string(settings.batch) +
                 ", history " + std::to_string(settings.historyFrames));
    std::vector<int> outputs;
    for (const BatchPlan& batch : plan) {
      ASSERT_EQ(batch.first, outputs.size());
      ASSERT_FALSE(batch.frames.empty());
      ASSERT_LE(batch.frames.size(), static_cast<std::size_t>(settings.batch));
      ASSERT_TRUE(batch.restart);
      EXPECT_EQ(batch.warmup,
                framesBeforeByScan(shot.source, batch.frames[0], settings.historyFrames));
      const std::vector<int> solve = batch.solveFrames();
      for (std::size_t i = 0; i < batch.frames.size(); ++i) {
        const std::size_t p = batch.warmup.size() + i;
        EXPECT_EQ(walkedHistory(solve, p, settings.historyFrames),
                  idealHistory(solve[p], shot.source, settings.historyFrames))
            << "frame " << solve[p] << " evaluated after " << describe(solve);
      }
      outputs.insert(outputs.end(), batch.frames.begin(), batch.frames.end());
    }
    ASSERT_EQ(outputs, shot.frames);
    // No batch is cut where history does not need it: consecutive frames share a batch
    // unless the batch is full.
    for (std::size_t b = 1; b < plan.size(); ++b) {
      const int before = plan[b - 1].frames.back();
      if (before + 1 == plan[b].frames[0]) {
        EXPECT_EQ(plan[b - 1].frames.size(), static_cast<std::size_t>(settings.batch));
      }
    }
  }
}

TEST(ShotPlan, TheTemporalBoundRestartsEveryBatchAfterItsWarmup) {
  const unsigned seed = testing::testSeed();
  std::mt19937 random(seed);
  for (int trial = 0; trial < 200; ++trial) {
    const RandomShot shot = randomShot(random);
    ShotPlanSettings settings;
    settings.batch = 1 + static_cast<int>(random() % 9);
    settings.temporalBound = true;
    settings.temporalWarmup = static_cast<int>(random() % 10);
    const std::vector<int> available(shot.source.begin(), shot.source.end());
    const std::vector<BatchPlan> plan = planShot(shot.frames, available, settings);
    SCOPED_TRACE("seed " + std::to_string(seed) + ", trial " + std::to_string(trial));
    // Without history the bake cuts batches by count alone: frame i is in batch i / batch,
    // and the bound runs through gaps within a batch.
    const std::size_t expected = (shot.frames.size() + settings.batch - 1) / settings.batch;
    ASSERT_EQ(plan.size(), expected);
    for (std::size_t b = 0; b < plan.size(); ++b) {
      const std::size_t first = b * settings.batch;
      const std::size_t last = std::min(shot.frames.size(), first + settings.batch);
      EXPECT_EQ(plan[b].first, first);
      EXPECT_EQ(plan[b].frames,
                std::vector<int>(shot.frames.begin() + first, shot.frames.begin() + last));
      EXPECT_EQ(plan[b].warmup,
                framesBeforeByScan(shot.source, shot.frames[first], settings.temporalWarmup));
    }
  }
  // The warm-up is the larger of the two needs when both are there.
  ShotPlanSettings both;
  both.temporalBound = true;
  both.temporalWarmup = 3;
  both.historyFrames = 5;
  EXPECT_EQ(both.warmupFrames(), 5);
  both.temporalBound = false;
  both.historyFrames = 0;
  EXPECT_EQ(both.warmupFrames(), 0) << "no warm-up without the bound and without history";
  EXPECT_EQ(planShot({10, 11}, {5, 6, 7, 8, 9}, both)[0].warmup, std::vector<int>());
}

/// What a playback's evaluator has solved since its last restart, against the whole bake of the
/// run of consecutive frames the playback is in (tracked here, not by the planner).
TEST(ShotPlan, PlaybackFramesAreTheFramesOfABakeOfTheirRun) {
  const unsigned seed = testing::testSeed();
  std::mt19937 random(seed);
  for (int trial = 0; trial < 200; ++trial) {
    const RandomShot shot = randomShot(random);
    ShotPlanSettings settings;
    settings.batch = 1 + static_cast<int>(random() % 9);
    const bool bound = trial % 2 == 1;
    settings.temporalBound = bound;
    settings.temporalWarmup = static_cast<int>(random() % 6);
    settings.historyFrames = bound ? 0 : 1 + static_cast<int>(random() % 15);
    const int history = settings.warmupFrames();
    const std::vector<int> available(shot.source.begin(), shot.source.end());
    PlaybackPlanner planner(settings);
    std::vector<int> solved;  // since the evaluator's last restart
    int runStart = 0;
    for (std::size_t i = 0; i < shot.frames.size(); ++i) {
      const int frame = shot.frames[i];
      SCOPED_TRACE("seed " + std::to_string(seed) + ", trial " + std::to_string(trial) +
                   ", frames " + describe(shot.frames) + ", step " + std::to_string(i));
      const bool runs = i > 0 && shot.frames[i - 1] + 1 == frame;
      runStart = runs ? runStart : frame;
      const BatchPlan step = planner.next(frame, available);
      ASSERT_EQ(step.frames, std::vector<int>{frame});
      if (step.restart) {
        solved.clear();
      }
      solved.insert(solved.end(), step.warmup.begin(), step.warmup.end());
      solved.push_back(frame);
      if (bound) {
        // The bake of runStart..frame restarts the bound every `batch` frames.
        const int batchStart = runStart + (frame - runStart) / settings.batch * settings.batch;
        std::vector<int> chain = framesBeforeByScan(shot.source, batchStart, history);
        for (int f = batchStart; f <= frame; ++f) {
          chain.push_back(f);
        }
        EXPECT_EQ(solved, chain);
      } else {
        EXPECT_EQ(walkedHistory(solved, solved.size() - 1, history),
                  idealHistory(frame, shot.source, history))
            << "frame " << frame << " after " << describe(solved);
        EXPECT_EQ(step.restart, !runs) << "only a jump restarts without the bound";
      }
    }
  }
}

TEST(ShotPlan, OutOfRangeSettingsAreUsageErrorsNamingTheSetting) {
  ShotPlanSettings settings;
  settings.batch = 0;
  try {
    planShot({1}, {1}, settings);
    FAIL() << "batch 0 was accepted";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kUsage);
    EXPECT_NE(std::string(error.what()).find("batch size must be at least 1 frame (got 0)"),
              std::string::npos)
        << error.what();
  }
  settings.batch = 1;
  settings.temporalWarmup = -2;
  try {
    PlaybackPlanner planner(settings);
    FAIL() << "a warm-up of -2 was accepted";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kUsage);
    EXPECT_NE(std::string(error.what()).find("temporal warm-up must be >= 0 frames (got -2)"),
              std::string::npos)
        << error.what();
  }
}

TEST(ShotPlan, TheEndsOfTheFrameNumbersAreFramesLikeAnyOther) {
  ShotPlanSettings settings;
  settings.historyFrames = 3;
  const std::vector<BatchPlan> plan = planShot(
      {INT_MIN, INT_MIN + 1, INT_MAX}, {INT_MIN, INT_MIN + 1, INT_MAX - 1, INT_MAX}, settings);
  ASSERT_EQ(plan.size(), 2u);
  EXPECT_EQ(plan[0].warmup, std::vector<int>());
  EXPECT_EQ(plan[0].frames, (std::vector<int>{INT_MIN, INT_MIN + 1}));
  EXPECT_EQ(plan[1].warmup, std::vector<int>{INT_MAX - 1});
  PlaybackPlanner planner(settings);
  EXPECT_TRUE(planner.next(INT_MAX, {INT_MAX}).restart);
  EXPECT_TRUE(planner.next(INT_MIN, {INT_MIN}).restart) << "INT_MIN does not follow INT_MAX";
}

/// The settings an Evaluator gives: its history frames, the bound only when its settings run
/// it, the batch lowered to the memory budget only without the bound.
TEST(ShotPlan, AnEvaluatorGivesItsHistoryItsBoundAndItsMemoryBudget) {
  testing::Backends host = hostBackends();
  const Database& qpDb = sampleDatabase();
  EvaluatorSettings qp;
  qp.weightMode = WeightMode::kQp;
  const Evaluator plain(qpDb, qp, host.view());
  ShotPlanSettings settings = shotPlanSettings(plain, 16, 5);
  EXPECT_EQ(settings.historyFrames, 0);
  EXPECT_FALSE(settings.temporalBound);
  EXPECT_EQ(settings.warmupFrames(), 0);
  EXPECT_EQ(settings.batch, 16);
  const std::size_t fit = kBatchMemoryBudget / plain.bytesPerFrame();
  ASSERT_LT(fit, static_cast<std::size_t>(INT_MAX));
  EXPECT_EQ(shotPlanSettings(plain, INT_MAX, 5).batch, static_cast<int>(fit));

  qp.maxWeightChange = 0.05;
  const Evaluator bound(qpDb, qp, host.view());
  settings = shotPlanSettings(bound, INT_MAX, 5);
  EXPECT_TRUE(settings.temporalBound);
  EXPECT_EQ(settings.warmupFrames(), 5);
  EXPECT_EQ(settings.batch, INT_MAX) << "with the bound the batch decides the cloth";

  const Database poseDb = buildSample(12, {}, true);
  const Evaluator pose(poseDb, EvaluatorSettings(), host.view());
  ASSERT_GT(pose.historyFrames(), 0);
  settings = shotPlanSettings(pose, 64, 8);
  EXPECT_EQ(settings.historyFrames, pose.historyFrames());
  EXPECT_FALSE(settings.temporalBound);
  EXPECT_EQ(settings.warmupFrames(), pose.historyFrames());
  EXPECT_THROW(shotPlanSettings(pose, 0, 8), Error);
}

}  // namespace
}  // namespace drivenshape
