// SPDX-License-Identifier: Apache-2.0
// Simulating what the verdict flags (src/shot/simulation.cpp, issue 44): the windows against a
// brute-force marking of the frames each needs, the plan from hand-written bake reports, its
// JSON both ways, and the splice against numbers worked out by hand and against a per-frame
// reference written apart from the library's per-window loop.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <drivenshape/coverage_check.h>
#include <drivenshape/error.h>
#include <drivenshape/simulation.h>

#include "test_support.h"

namespace drivenshape {
namespace {

using testing::expectThrows;

// ---- Windows ----------------------------------------------------------------------------

/// The windows by marking frames: the hand-back span of each group of flagged frames at most
/// `gap` apart, its warm-up before it (not before `first`); every stretch of marked frames is a
/// window, handing back from its first flagged frame to its last.
std::vector<SimulationWindow> markedWindows(const std::vector<int>& flagged, int first, int last,
                                            int warmup, int gap) {
  const auto at = [&](int f) { return static_cast<std::size_t>(f - first); };
  std::vector<bool> marked(at(last) + 1, false), isFlagged(marked);
  for (std::size_t i = 0; i < flagged.size();) {
    std::size_t j = i;
    while (j + 1 < flagged.size() && flagged[j + 1] - flagged[j] - 1 <= gap) {
      ++j;
    }
    for (int f = std::max(first, flagged[i] - warmup); f <= flagged[j]; ++f) {
      marked[at(f)] = true;
    }
    i = j + 1;
  }
  for (int f : flagged) {
    isFlagged[at(f)] = true;
  }
  std::vector<SimulationWindow> windows;
  for (int f = first; f <= last; ++f) {
    if (!marked[at(f)]) {
      continue;
    }
    if (f == first || !marked[at(f - 1)]) {
      windows.push_back({f, 0, 0, 0});
    }
    if (isFlagged[at(f)]) {
      SimulationWindow& window = windows.back();
      window.from = window.wanted == 0 ? f : window.from;
      window.to = f;
      ++window.wanted;
    }
  }
  return windows;
}

TEST(SimulationWindows, MatchMarkingTheFramesEachNeeds) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 400; ++trial) {
    const int first = static_cast<int>(rng() % 50) - 10;
    const int span = 1 + static_cast<int>(rng() % 200);
    const int warmup = static_cast<int>(rng() % 30);
    const int gap = static_cast<int>(rng() % 15);
    const double share = (rng() % 100) / 300.0;
    std::vector<int> flagged;
    for (int f = first; f < first + span; ++f) {
      if ((rng() % 1000) / 1000.0 < share) {
        flagged.push_back(f);
      }
    }
    const std::vector<SimulationWindow> expected =
        markedWindows(flagged, first, first + span - 1, warmup, gap);
    const std::vector<SimulationWindow> windows = simulationWindows(flagged, first, warmup, gap);
    ASSERT_EQ(windows.size(), expected.size()) << "trial " << trial;
    for (std::size_t w = 0; w < windows.size(); ++w) {
      EXPECT_EQ(windows[w].warmupFrom, expected[w].warmupFrom) << "trial " << trial << " " << w;
      EXPECT_EQ(windows[w].from, expected[w].from) << "trial " << trial << " " << w;
      EXPECT_EQ(windows[w].to, expected[w].to) << "trial " << trial << " " << w;
      EXPECT_EQ(windows[w].wanted, expected[w].wanted) << "trial " << trial << " " << w;
    }
  }
}

TEST(SimulationWindows, HandExamples) {
  // 30-32 and 40 are 7 frames apart: one window with a gap of 10; 70 is 29 after 40, and its
  // warm-up (from 50) starts after 41: a window of its own.
  const std::vector<SimulationWindow> merged = simulationWindows({30, 31, 32, 40, 70}, 1, 20, 10);
  ASSERT_EQ(merged.size(), 2u);
  EXPECT_EQ(merged[0].warmupFrom, 10);
  EXPECT_EQ(merged[0].from, 30);
  EXPECT_EQ(merged[0].to, 40);
  EXPECT_EQ(merged[0].wanted, 4);
  EXPECT_EQ(merged[1].warmupFrom, 50);
  EXPECT_EQ(merged[1].from, 70);
  // Without the gap, with a warm-up of 5: three windows, 35-40 apart from 25-32.
  const std::vector<SimulationWindow> apart = simulationWindows({30, 31, 32, 40, 70}, 1, 5, 0);
  ASSERT_EQ(apart.size(), 3u);
  EXPECT_EQ(apart[1].warmupFrom, 35);
  EXPECT_EQ(apart[1].from, 40);
  // A warm-up of 7 starts 40's at 33, touching 32: merged, handing back 30-40.
  const std::vector<SimulationWindow> touching = simulationWindows({30, 31, 32, 40}, 1, 7, 0);
  ASSERT_EQ(touching.size(), 1u);
  EXPECT_EQ(touching[0].from, 30);
  EXPECT_EQ(touching[0].to, 40);
  // Never before the shot's first frame.
  EXPECT_EQ(simulationWindows({3}, 1, 20, 0).front().warmupFrom, 1);
  EXPECT_TRUE(simulationWindows({}, 1, 20, 10).empty());
  expectThrows([] { simulationWindows({5, 4}, 1, 20, 10); }, ErrorCode::kInternal, "ascending");
  expectThrows([] { simulationWindows({5}, 1, -1, 10); }, ErrorCode::kInternal, "warm-up");
}

// ---- The plan ---------------------------------------------------------------------------

/// A bake report of frames first..last, flagging `flagged`, with or without predictions.
BakeReportCoverage report(int first, int last, const std::vector<int>& flagged,
                          bool predicted = true) {
  std::string frames;
  for (int f = first; f <= last; ++f) {
    bool flag = false;
    for (int g : flagged) {
      flag = flag || g == f;
    }
    frames += (frames.empty() ? "" : ",") + std::string("{\"frame\":") + std::to_string(f) +
              (predicted ? std::string(",\"predicted_error\":0.01,\"coverage\":{\"flagged\":") +
                               (flag ? "true" : "false") + "}"
                         : "") +
              "}";
  }
  return parseBakeReportCoverage("{\"coverage\":{\"tolerance\":0.02},\"frames\":[" + frames + "]}",
                                 "x.report.json");
}

TEST(SimulationPlan, FromTheReportsFlaggedFrames) {
  SimulationOptions settings;
  settings.warmup = 5;
  settings.mergeGap = 2;
  const SimulationPlan plan = planSimulation(report(101, 160, {110, 111, 114, 140}), settings);
  EXPECT_EQ(plan.first, 101);
  EXPECT_EQ(plan.last, 160);
  EXPECT_EQ(plan.report, "x.report.json");
  ASSERT_EQ(plan.windows.size(), 2u);
  EXPECT_EQ(plan.windows[0].warmupFrom, 105);
  EXPECT_EQ(plan.windows[0].from, 110);
  EXPECT_EQ(plan.windows[0].to, 114);
  EXPECT_EQ(plan.windows[1].warmupFrom, 135);
  EXPECT_EQ(plan.simulatedFrames(), 10 + 6);
  // From the start: one window handing back the first to the last flagged frame.
  settings.fromStart = true;
  const SimulationPlan whole = planSimulation(report(101, 160, {110, 140}), settings);
  ASSERT_EQ(whole.windows.size(), 1u);
  EXPECT_EQ(whole.windows[0].warmupFrom, 101);
  EXPECT_EQ(whole.windows[0].from, 110);
  EXPECT_EQ(whole.windows[0].to, 140);
  EXPECT_TRUE(planSimulation(report(1, 10, {}), settings).windows.empty());
}

TEST(SimulationPlan, RefusesWhatItCannotPlan) {
  expectThrows([] { planSimulation(report(1, 10, {}, false), {}); }, ErrorCode::kInput,
               "no frame has a predicted error");
  const BakeReportCoverage holed =
      parseBakeReportCoverage(R"({"frames":[{"frame":1},{"frame":2},{"frame":4}]})", "holed.json");
  expectThrows([&] { planSimulation(holed, {}); }, ErrorCode::kInput, "frame 3 is missing");
  SimulationOptions bad;
  bad.goalStrength = 1.5;
  expectThrows([&] { planSimulation(report(1, 10, {5}), bad); }, ErrorCode::kUsage,
               "--goal-strength");
  bad = {};
  bad.warmup = -1;
  expectThrows([&] { planSimulation(report(1, 10, {5}), bad); }, ErrorCode::kUsage, "--warmup");
}

TEST(SimulationPlan, JsonRoundTrip) {
  SimulationOptions settings;
  settings.warmup = 20;  // the numbers below are worked with it
  settings.goalStrength = 0.25;
  settings.seam = 3;
  settings.carry = 7;
  const SimulationPlan plan = planSimulation(report(1, 100, {30, 31, 80}), settings);
  const std::string text = simulationPlanJson(plan);
  const SimulationPlan back = parseSimulationPlan(text, "plan.json");
  EXPECT_EQ(simulationPlanJson(back), text);
  EXPECT_EQ(back.settings.goalStrength, 0.25);
  EXPECT_EQ(back.settings.carry, 7);
  ASSERT_EQ(back.windows.size(), 2u);
  EXPECT_EQ(back.windows[1].warmupFrom, 60);
  EXPECT_NE(text.find("\"format\": \"drivenshape-simulation-plan\""), std::string::npos);
  EXPECT_NE(text.find("\"simulated_frames\": 43"), std::string::npos);  // 10-31, 60-80
}

TEST(SimulationPlan, ReaderRefusesOtherText) {
  SimulationOptions settings;
  settings.warmup = 20;  // the windows' text below is worked with it
  const SimulationPlan plan = planSimulation(report(1, 100, {30, 80}), settings);
  const std::string good = simulationPlanJson(plan);
  const auto with = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    const std::size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return text.replace(at, from.size(), to);
  };
  const auto refused = [](const std::string& text, const std::string& fragment) {
    expectThrows([&] { parseSimulationPlan(text, "p.json"); }, ErrorCode::kInput, fragment);
  };
  refused("[]", "not a simulation plan");
  refused(with("\"version\": 1", "\"version\": 2"), "version 2");
  refused(with("\"seam\": 4", "\"seam\": -4"), "seam");
  refused(with("\"seam\": 4", "\"seem\": 4"), "settings.seam is missing");
  refused(with("\"warmup_from\": 60", "\"warmup_from\": 29"), "windows[1]");
  refused(with("\"to\": 80", "\"to\": 101"), "windows[1]");
  refused(with("\"simulated_frames\": 42", "\"simulated_frames\": 41"), "simulated_frames");
  refused(with("\"from_start\": false", "\"from_start\": 0"), "from_start");
  refused("{\"format\": \"drivenshape-simulation-plan\"", "not valid JSON");
}

// ---- The splice -------------------------------------------------------------------------

SimulationPlan handPlan(int first, int last, std::vector<SimulationWindow> windows, int seam,
                        int carry) {
  SimulationPlan plan;
  plan.first = first;
  plan.last = last;
  plan.windows = std::move(windows);
  plan.settings.seam = seam;
  plan.settings.carry = carry;
  return plan;
}

/// Two vertices; every coordinate c (0..5) of frame f baked at f and simulated at f + 100 + c.
std::vector<float> bakedFrames(int first, int last) {
  std::vector<float> out;
  for (int f = first; f <= last; ++f) {
    out.insert(out.end(), 6, static_cast<float>(f));
  }
  return out;
}

std::vector<float> simulatedFrames(int from, int to) {
  std::vector<float> out;
  for (int f = from; f <= to; ++f) {
    for (int c = 0; c < 6; ++c) {
      out.push_back(static_cast<float>(f + 100 + c));
    }
  }
  return out;
}

std::string sourcesText(const SplicedShot& shot) {
  std::string text;
  for (FrameSource source : shot.sources) {
    text += source == FrameSource::kBaked ? 'B' : source == FrameSource::kSimulated ? 'S' : 'L';
  }
  return text;
}

TEST(Splice, HandExample) {
  // Frames 1-12, one window simulating 3-7 and handing back 6-7, seam 2, carry 3.
  const SimulationPlan plan = handPlan(1, 12, {{3, 6, 7, 2}}, 2, 3);
  const SplicedShot shot = spliceSimulation(plan, 2, bakedFrames(1, 12), {simulatedFrames(3, 7)});
  EXPECT_EQ(sourcesText(shot), "BBBLLSSLLLBB");
  // Coordinates 0 and 5 of each frame, worked out by hand: the seam's weights are 1/3 and 2/3;
  // the residual at 7 is 100 + c, carried at 3/4, 1/2, 1/4.
  const float expected[12][2] = {{1, 1},           {2, 2},       {3, 3},     {37.333333f, 39},
                                 {71.666667f, 75}, {106, 111},   {107, 112}, {83, 86.75f},
                                 {59, 61.5f},      {35, 36.25f}, {11, 11},   {12, 12}};
  for (int f = 0; f < 12; ++f) {
    EXPECT_FLOAT_EQ(shot.positions[f * 6 + 0], expected[f][0]) << "frame " << f + 1;
    EXPECT_FLOAT_EQ(shot.positions[f * 6 + 5], expected[f][1]) << "frame " << f + 1;
  }
}

TEST(Splice, EdgesOfTheShotAndOfTheSettings) {
  // A window at the shot's start (no warm-up, so no seam) and one at its end (no carry).
  const SimulationPlan ends = handPlan(1, 10, {{1, 1, 2, 2}, {6, 9, 10, 2}}, 2, 2);
  const SplicedShot atEnds = spliceSimulation(ends, 2, bakedFrames(1, 10),
                                              {simulatedFrames(1, 2), simulatedFrames(6, 10)});
  EXPECT_EQ(sourcesText(atEnds), "SSLLBBLLSS");
  EXPECT_FLOAT_EQ(atEnds.positions[0], 101.0f);
  // Windows closer than seam + carry: the carry of the first stops before the second's seam.
  const SimulationPlan close = handPlan(1, 12, {{1, 3, 4, 2}, {7, 9, 10, 2}}, 2, 5);
  const SplicedShot near = spliceSimulation(close, 2, bakedFrames(1, 12),
                                            {simulatedFrames(1, 4), simulatedFrames(7, 10)});
  EXPECT_EQ(sourcesText(near), "LLSSLLLLSSLL");
  EXPECT_FLOAT_EQ(near.positions[4 * 6], 5.0f + 100.0f * 5.0f / 6.0f);  // frame 5, k = 1
  EXPECT_FLOAT_EQ(near.positions[6 * 6], 7.0f + 100.0f / 3.0f);         // frame 7, seam 1/3
  // Seam 0 and carry 0: a hard cut on both sides.
  const SimulationPlan cut = handPlan(1, 8, {{2, 4, 5, 2}}, 0, 0);
  const SplicedShot hard = spliceSimulation(cut, 2, bakedFrames(1, 8), {simulatedFrames(2, 5)});
  EXPECT_EQ(sourcesText(hard), "BBBSSBBB");
  EXPECT_EQ(hard.positions[2 * 6], 3.0f);
  EXPECT_EQ(hard.positions[5 * 6], 6.0f);
  // No window: the bake, bit for bit.
  const std::vector<float> baked = bakedFrames(1, 5);
  EXPECT_EQ(spliceSimulation(handPlan(1, 5, {}, 4, 10), 2, baked, {}).positions, baked);
}

/// The splice frame by frame: what each frame is, found from the windows around it.
std::vector<float> referenceSplice(const SimulationPlan& plan, int vertexCount,
                                   const std::vector<float>& baked,
                                   const std::vector<std::vector<float>>& simulated) {
  const std::size_t n = 3 * static_cast<std::size_t>(vertexCount);
  std::vector<float> out(baked);
  const int seam = plan.settings.seam, carry = plan.settings.carry;
  for (int f = plan.first; f <= plan.last; ++f) {
    const float* b = &baked[(f - plan.first) * n];
    float* o = &out[(f - plan.first) * n];
    for (std::size_t w = 0; w < plan.windows.size(); ++w) {
      const SimulationWindow& win = plan.windows[w];
      const int s = std::min(seam, win.from - win.warmupFrom);
      const auto sim = [&](int g) { return &simulated[w][(g - win.warmupFrom) * n]; };
      if (f >= win.from && f <= win.to) {
        std::copy(sim(f), sim(f) + n, o);
      } else if (f >= win.from - s && f < win.from) {
        const double weight = (f - (win.from - s) + 1.0) / (s + 1.0);
        for (std::size_t i = 0; i < n; ++i) {
          o[i] = static_cast<float>((1.0 - weight) * b[i] + weight * sim(f)[i]);
        }
      } else if (f > win.to && f <= win.to + carry) {
        const bool beforeNext =
            w + 1 == plan.windows.size() ||
            f < plan.windows[w + 1].from -
                    std::min(seam, plan.windows[w + 1].from - plan.windows[w + 1].warmupFrom);
        if (beforeNext) {
          const double fade = (carry + 1.0 - (f - win.to)) / (carry + 1.0);
          const float* bt = &baked[(win.to - plan.first) * n];
          for (std::size_t i = 0; i < n; ++i) {
            o[i] = static_cast<float>(b[i] + fade * (sim(win.to)[i] - static_cast<double>(bt[i])));
          }
        }
      }
    }
  }
  return out;
}

TEST(Splice, MatchesAFrameByFrameReference) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> value(-2.0f, 2.0f);
  for (int trial = 0; trial < 200; ++trial) {
    const int first = static_cast<int>(rng() % 20), last = first + 5 + static_cast<int>(rng() % 60);
    std::vector<int> flagged;
    for (int f = first; f <= last; ++f) {
      if (rng() % 6 == 0) {
        flagged.push_back(f);
      }
    }
    SimulationPlan plan =
        handPlan(first, last, {}, static_cast<int>(rng() % 6), static_cast<int>(rng() % 12));
    plan.windows =
        simulationWindows(flagged, first, static_cast<int>(rng() % 8), static_cast<int>(rng() % 4));
    const int vertices = 1 + static_cast<int>(rng() % 3);
    std::vector<float> baked(static_cast<std::size_t>(last - first + 1) * 3 * vertices);
    for (float& x : baked) {
      x = value(rng);
    }
    std::vector<std::vector<float>> simulated;
    for (const SimulationWindow& window : plan.windows) {
      simulated.emplace_back(static_cast<std::size_t>(window.to - window.warmupFrom + 1) * 3 *
                             vertices);
      for (float& x : simulated.back()) {
        x = value(rng);
      }
    }
    const std::vector<float> expected = referenceSplice(plan, vertices, baked, simulated);
    const std::vector<float> got = spliceSimulation(plan, vertices, baked, simulated).positions;
    ASSERT_EQ(got.size(), expected.size());
    for (std::size_t i = 0; i < got.size(); ++i) {
      // (1 - w) b + w s against b + w (s - b): the same number up to the rounding of doubles.
      ASSERT_NEAR(got[i], expected[i], 1e-6f) << "trial " << trial << " value " << i;
    }
  }
}

TEST(Splice, RefusesArraysOfAnotherSize) {
  const SimulationPlan plan = handPlan(1, 10, {{3, 5, 6, 2}}, 2, 2);
  expectThrows([&] { spliceSimulation(plan, 2, bakedFrames(1, 9), {simulatedFrames(3, 6)}); },
               ErrorCode::kUsage, "the baked frames");
  expectThrows([&] { spliceSimulation(plan, 2, bakedFrames(1, 10), {simulatedFrames(3, 5)}); },
               ErrorCode::kUsage, "simulated window 0 (frames 3-6)");
  expectThrows([&] { spliceSimulation(plan, 2, bakedFrames(1, 10), {}); }, ErrorCode::kUsage,
               "0 simulated windows");
  std::vector<float> bad = simulatedFrames(3, 6);
  bad[6 + 4] = std::numeric_limits<float>::quiet_NaN();
  expectThrows([&] { spliceSimulation(plan, 2, bakedFrames(1, 10), {bad}); }, ErrorCode::kNumerical,
               "frame 4, vertex 1");
}

}  // namespace
}  // namespace drivenshape
