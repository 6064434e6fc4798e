// SPDX-License-Identifier: Apache-2.0
// The coverage check of `drivenshape eval --report` (src/shot/coverage_check.cpp): average ranks
// and Spearman's correlation against a brute-force reference (ties included), the bake report
// reader on hand-written reports, the merge of chunk reports on bad ones, and the matching of
// predictions to measured errors.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <drivenshape/bake.h>
#include <drivenshape/coverage_check.h>
#include <drivenshape/error.h>

#include "test_support.h"

namespace drivenshape {
namespace {

using testing::countedRanks;
using testing::expectThrows;
using testing::kRankCorrelationTol;
using testing::referencePearson;

TEST(RankCorrelation, AverageRanksOfAHandExample) {
  // 0.3 once, 0.1 twice (positions 1 and 2), 0.7 three times (positions 4, 5, 6).
  const std::vector<double> ranks = averageRanks({0.7, 0.1, 0.3, 0.7, 0.1, 0.7});
  const std::vector<double> expected = {5.0, 1.5, 3.0, 5.0, 1.5, 5.0};
  EXPECT_EQ(ranks, expected);
}

TEST(RankCorrelation, MatchesBruteForceWithAndWithoutTies) {
  const std::uint32_t seed = testing::testSeed();
  std::mt19937 rng(seed);
  int compared = 0, tied = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int n = 2 + trial % 40;
    // Few distinct levels on every other trial (many ties), continuous values otherwise.
    const int levels = trial % 2 == 0 ? 1 + trial % 5 : 0;
    std::uniform_int_distribution<int> level(0, std::max(levels - 1, 0));
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<double> x, y;
    for (int i = 0; i < n; ++i) {
      x.push_back(levels > 0 ? 0.25 * level(rng) : unit(rng));
      // y partly follows x, so the correlations spread over [-1, 1].
      y.push_back(levels > 0 && trial % 4 == 0 ? 0.5 * level(rng) : unit(rng) + 0.5 * x.back());
    }
    const std::string where = "trial " + std::to_string(trial) + " (seed " + std::to_string(seed) +
                              ", n " + std::to_string(n) + ")";
    const std::vector<double> rx = countedRanks(x), ry = countedRanks(y);
    ASSERT_EQ(averageRanks(x), rx) << where;  // exact: every rank is a whole number or a half
    ASSERT_EQ(averageRanks(y), ry) << where;
    const double expected = referencePearson(rx, ry);
    const std::optional<double> rho = spearmanCorrelation(x, y);
    if (std::isnan(expected)) {
      EXPECT_FALSE(rho.has_value()) << where << ": a constant side has no correlation";
      continue;
    }
    ASSERT_TRUE(rho.has_value()) << where;
    EXPECT_NEAR(*rho, expected, kRankCorrelationTol) << where;
    ++compared;
    tied += levels > 0 ? 1 : 0;
  }
  EXPECT_GT(compared, 300);
  EXPECT_GT(tied, 100);  // the ties were exercised
}

TEST(RankCorrelation, DistinctValuesFollowTheTextbookFormula) {
  // Without ties, rho = 1 - 6 sum d^2 / (n (n^2 - 1)) with d the rank differences.
  std::mt19937 rng(testing::testSeed());
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int n : {2, 3, 7, 30}) {
    std::vector<double> x, y;
    for (int i = 0; i < n; ++i) {
      x.push_back(unit(rng));
      y.push_back(unit(rng));
    }
    const std::vector<double> rx = countedRanks(x), ry = countedRanks(y);
    double d2 = 0.0;
    for (int i = 0; i < n; ++i) {
      d2 += (rx[i] - ry[i]) * (rx[i] - ry[i]);
    }
    const double expected = 1.0 - 6.0 * d2 / (n * (double(n) * n - 1.0));
    EXPECT_NEAR(spearmanCorrelation(x, y).value(), expected, kRankCorrelationTol) << "n " << n;
  }
}

TEST(RankCorrelation, MonotoneOrderGivesPlusOrMinusOne) {
  const std::vector<double> x = {0.1, 0.5, 0.2, 0.9, 0.3};
  std::vector<double> cubed, negated;
  for (double v : x) {
    cubed.push_back(v * v * v);
    negated.push_back(-v);
  }
  EXPECT_EQ(spearmanCorrelation(x, cubed).value(), 1.0);
  EXPECT_EQ(spearmanCorrelation(x, negated).value(), -1.0);
}

TEST(RankCorrelation, UndefinedAndBadInput) {
  EXPECT_FALSE(spearmanCorrelation({}, {}).has_value());
  EXPECT_FALSE(spearmanCorrelation({0.5}, {0.2}).has_value());
  EXPECT_FALSE(spearmanCorrelation({0.5, 0.5, 0.5}, {0.1, 0.2, 0.3}).has_value());
  expectThrows(
      [] {
        spearmanCorrelation({1.0, 2.0}, {1.0});
      },
      ErrorCode::kInternal, "rank correlation of 2 values against 1");
  expectThrows(
      [] {
        spearmanCorrelation({1.0, std::nan("")}, {1.0, 2.0});
      },
      ErrorCode::kNumerical, "not finite");
}

// ---- The bake report reader ----

/// A report as `bake --report` writes it (the fields the reader uses, and some it skips).
std::string reportText(const std::string& frames, const std::string& extra = "") {
  return R"({"tool": "drivenshape", "database": {"shape_count": 5, "driven_vertices": 12},
             "settings": {"weights": "model"}, "coverage": {"tolerance": 0.5,
             "covered_fraction": 0.5, "verdict": "simulate 2"},)" +
         extra + R"("frames": [)" + frames + "]}";
}

TEST(BakeReportCoverage, ReadsPredictionsFlagsAndCounts) {
  const BakeReportCoverage r = parseBakeReportCoverage(
      reportText(R"({"frame": 1, "predicted_error": 0.25, "coverage": {"flagged": false}},
                    {"frame": 2, "predicted_error": 0.75, "coverage": {"flagged": true, "score": 1}},
                    {"frame": 3, "skipped": true},
                    {"frame": 4, "predicted_error": 0, "coverage": {"flagged": 0}},
                    {"frame": -5, "predicted_error": 1e-3, "coverage": true})"),
      "r.json");
  EXPECT_EQ(r.source, "r.json");
  ASSERT_EQ(r.predicted.size(), 4u);
  EXPECT_EQ(r.predicted[0].frame, 1);
  EXPECT_EQ(r.predicted[0].predictedError, 0.25);
  EXPECT_FALSE(r.predicted[0].flagged);
  EXPECT_EQ(r.predicted[1].frame, 2);
  EXPECT_TRUE(r.predicted[1].flagged);
  EXPECT_FALSE(r.predicted[2].flagged);
  EXPECT_EQ(r.predicted[3].frame, -5);
  EXPECT_TRUE(r.predicted[3].flagged);
  EXPECT_EQ(r.unpredicted, std::vector<int>{3});
  EXPECT_EQ(r.tolerance, 0.5);
  EXPECT_EQ(r.clothVertices, 12);
  EXPECT_EQ(r.weights, "model");

  // A QP bake: no predictions, no tolerance needed; no vertex count stated.
  const BakeReportCoverage qp = parseBakeReportCoverage(
      R"({"settings": {"weights": "qp"}, "frames": [{"frame": 1}, {"frame": 2}]})", "qp.json");
  EXPECT_TRUE(qp.predicted.empty());
  EXPECT_EQ(qp.unpredicted, (std::vector<int>{1, 2}));
  EXPECT_EQ(qp.clothVertices, -1);
  EXPECT_EQ(qp.weights, "qp");
}

TEST(BakeReportCoverage, BadReportsNameTheFileAndTheProblem) {
  auto bad = [](const std::string& text, const std::string& fragment) {
    expectThrows([&] { parseBakeReportCoverage(text, "bad.json"); }, ErrorCode::kInput, fragment);
    expectThrows([&] { parseBakeReportCoverage(text, "bad.json"); }, ErrorCode::kInput, "bad.json");
  };
  bad("not json", "not valid JSON");
  bad("[1, 2]", "no \"frames\" array");
  bad(R"({"frames": {"1": 0.5}})", "no \"frames\" array");
  bad(reportText("7"), "frames[0] is not an object");
  bad(reportText(R"({"frame": 1.5})"), "frame");
  bad(reportText(R"({"frame": 1}, {"frame": 1})"), "frame 1 is listed twice");
  bad(reportText(R"({"frame": 1, "predicted_error": -0.1, "coverage": {"flagged": false}})"),
      "predicted_error is -0.1");
  bad(reportText(R"({"frame": 1, "predicted_error": "low", "coverage": {"flagged": false}})"),
      "predicted_error is \"low\"");
  bad(reportText(R"({"frame": 1, "predicted_error": 0.1})"), "no coverage.flagged");
  bad(reportText(R"({"frame": 1, "predicted_error": 0.1, "coverage": {"flagged": 2}})"),
      "coverage.flagged");
  bad(R"({"frames": [{"frame": 1, "predicted_error": 0.1, "coverage": {"flagged": true}}]})",
      "coverage.tolerance is missing");
  bad(R"({"coverage": {"tolerance": "2%"}, "frames": [{"frame": 1, "predicted_error": 0.1,
          "coverage": {"flagged": true}}]})",
      "coverage.tolerance is \"2%\"");
  bad(R"({"database": {"driven_vertices": 0}, "frames": []})", "database.driven_vertices");
}

TEST(MergeBakeReports, BadReportsNameTheSourceAndTheEntry) {
  auto bad = [](const std::string& text, const std::string& fragment) {
    for (const std::string& want : {fragment, std::string("part2.json")}) {
      expectThrows(
          [&] {
            mergeBakeReports({"{\"frames\": []}", text}, {"part1.json", "part2.json"});
          },
          ErrorCode::kInput, want);
    }
  };
  bad("not json", "not valid JSON");
  bad(R"({"frames": 3})", "no \"frames\" list");
  bad(R"({"frames": [{"skipped": true}]})", "frames[0] is a kept frame without a \"frame\"");
  bad(R"({"frames": [7]})", "frames[0] is 7");
  bad(R"({"frames": [{"frame": 2}]})", "frames[0] has no relative_residual");
  bad(R"({"settings_hash": "x", "frames": []})", "its settings_hash differs from that of part1");
  bad(R"({"frames": [], "seconds": [1]})", "seconds is [1]");
}

// ---- Predictions against measured errors ----

/// An evaluation of `vertices` cloth vertices whose bake has these per-frame mean errors.
ShotEvaluation evaluation(const std::vector<std::pair<int, double>>& frameErrors,
                          int vertices = 12) {
  ShotEvaluation e;
  e.vertexCount = vertices;
  e.bake.source = "bake.####.exr";
  for (const auto& [frame, mean] : frameErrors) {
    e.frames.push_back(frame);
    ClothFrameMetrics m;
    m.frame = frame;
    m.error.frame = frame;
    m.error.mean = mean;
    e.bake.frames.push_back(m);
  }
  return e;
}

TEST(CoverageCheck, MatchesFramesAndSummarisesTheVerdict) {
  BakeReportCoverage report;
  report.source = "r.json";
  report.tolerance = 0.5;
  report.clothVertices = 12;
  // Frames 10..15 predicted (13 and 15 flagged), 16 listed without a prediction.
  report.predicted = {{10, 0.1, false}, {11, 0.3, false}, {12, 0.2, false},
                      {13, 0.9, true},  {14, 0.4, false}, {15, 0.6, true}};
  report.unpredicted = {16};
  // Evaluated in another order than the report's, with frames 16 and 17 the report lacks.
  const ShotEvaluation e = evaluation(
      {{14, 0.45}, {17, 1.0}, {10, 0.05}, {13, 0.8}, {16, 0.3}, {12, 0.6}, {11, 0.2}, {15, 0.7}});
  const CoverageCheck c = checkCoverage(report, e);
  ASSERT_EQ(c.frames.size(), 6u);
  const int order[] = {14, 10, 13, 12, 11, 15};  // the evaluation's order
  for (std::size_t i = 0; i < c.frames.size(); ++i) {
    EXPECT_EQ(c.frames[i].frame, order[i]);
  }
  EXPECT_EQ(c.frames[0].predictedError, 0.4);
  EXPECT_EQ(c.frames[0].trueError, 0.45);
  EXPECT_TRUE(c.frames[2].flagged);
  EXPECT_EQ(c.missing, 1);      // 17
  EXPECT_EQ(c.unpredicted, 1);  // 16
  EXPECT_EQ(c.tolerance, 0.5);
  EXPECT_EQ(c.enough, 4);
  EXPECT_EQ(c.flagged, 2);
  EXPECT_DOUBLE_EQ(c.coveredFraction, 4.0 / 6.0);
  EXPECT_DOUBLE_EQ(c.enoughTrueError.value(), (0.45 + 0.05 + 0.6 + 0.2) / 4.0);
  EXPECT_DOUBLE_EQ(c.flaggedTrueError.value(), (0.8 + 0.7) / 2.0);
  EXPECT_EQ(c.missed, 1);  // frame 12: 0.6 > 0.5 although predicted 0.2
  EXPECT_EQ(c.verdictHolds, std::optional<bool>(true));  // 0.325 <= 0.5
  // Predicted 0.4 0.1 0.9 0.2 0.3 0.6 against true 0.45 0.05 0.8 0.6 0.2 0.7.
  EXPECT_NEAR(c.spearman.value(),
              referencePearson(countedRanks({0.4, 0.1, 0.9, 0.2, 0.3, 0.6}),
                               countedRanks({0.45, 0.05, 0.8, 0.6, 0.2, 0.7})),
              kRankCorrelationTol);
  // What `eval --report` prints of the prediction: its mean and its largest frame.
  EXPECT_DOUBLE_EQ(c.predictedMean, (0.4 + 0.1 + 0.9 + 0.2 + 0.3 + 0.6) / 6.0);
  EXPECT_EQ(c.predictedMax, 0.9);
  EXPECT_EQ(c.predictedMaxFrame, 13);

  // Over the tolerance: the verdict fails.
  report.tolerance = 0.3;
  EXPECT_EQ(checkCoverage(report, e).verdictHolds, std::optional<bool>(false));
  // Every frame flagged: the verdict claims nothing, so it is not tested.
  for (PredictedFrame& p : report.predicted) {
    p.flagged = true;
  }
  const CoverageCheck all = checkCoverage(report, e);
  EXPECT_FALSE(all.verdictHolds.has_value());
  EXPECT_FALSE(all.enoughTrueError.has_value());
  EXPECT_EQ(all.coveredFraction, 0.0);
}

TEST(CoverageCheck, ReportsThatDoNotFitTheBake) {
  BakeReportCoverage report;
  report.source = "r.json";
  report.tolerance = 0.5;
  report.predicted = {{1, 0.1, false}, {2, 0.2, false}};
  report.clothVertices = 40;
  const ShotEvaluation e = evaluation({{1, 0.1}, {2, 0.3}});
  expectThrows([&] { checkCoverage(report, e); }, ErrorCode::kInput,
               "r.json: the report is of a bake of 40 cloth vertices, the bake 'bake.####.exr' "
               "has 12");
  report.clothVertices = -1;  // not stated: not checked
  EXPECT_EQ(checkCoverage(report, e).frames.size(), 2u);

  const ShotEvaluation later = evaluation({{5, 0.1}, {6, 0.3}});
  expectThrows([&] { checkCoverage(report, later); }, ErrorCode::kInput,
               "r.json: predicts frames 1-2 but none of the evaluated frames (5-6)");

  BakeReportCoverage qp;
  qp.source = "qp.json";
  qp.unpredicted = {1, 2};
  qp.weights = "qp";
  expectThrows([&] { checkCoverage(qp, e); }, ErrorCode::kInput,
               "qp.json: no frame has a predicted error (its weights are 'qp')");
  expectThrows([&] { checkCoverage(qp, e); }, ErrorCode::kInput, "pose model");
}

TEST(CoverageCheck, TheVerdictHoldsOnItsShareOrForOldReportsOnItsMean) {
  // At a level: the share truly within against the level, whatever the mean.
  EXPECT_TRUE(verdictHolds(10, 1, 0.5, 0.01, 0.9));     // 90% within
  EXPECT_FALSE(verdictHolds(10, 2, 0.001, 0.01, 0.9));  // 80%, the mean well within
  EXPECT_TRUE(verdictHolds(1, 0, 1.0, 0.01, 0.5));
  // Without a level (a report before 0.2.0): the true mean against the tolerance.
  EXPECT_TRUE(verdictHolds(10, 9, 0.01, 0.01, 0.0));
  EXPECT_FALSE(verdictHolds(10, 0, 0.0101, 0.01, 0.0));
  expectThrows([] { verdictHolds(0, 0, 0.0, 0.01, 0.9); }, ErrorCode::kInput, "at least 1");
  expectThrows([] { verdictHolds(3, 4, 0.0, 0.01, 0.9); }, ErrorCode::kInput, "4 missed");
  expectThrows([] { verdictHolds(3, 0, 0.0, 0.01, 1.0); }, ErrorCode::kInput, "level 1");
}

TEST(SimulationRuns, AreTheUnionOfEachFlaggedFramesRunUp) {
  // Against a brute force: every flagged frame f needs frames max(first, f - runUp)..f
  // simulated; the runs are the maximal stretches of needed frames, each with the flagged
  // frames inside it.
  std::mt19937 rng(5);
  for (int trial = 0; trial < 300; ++trial) {
    const int first = static_cast<int>(rng() % 50) - 10;
    const int runUp = static_cast<int>(rng() % 30);
    const int span = 1 + static_cast<int>(rng() % 200);
    const double share = (rng() % 100) / 100.0;
    std::vector<int> flagged;
    for (int f = first; f < first + span; ++f) {
      if ((rng() % 1000) / 1000.0 < share) {
        flagged.push_back(f);
      }
    }
    std::vector<bool> needed(static_cast<std::size_t>(span), false), wanted(needed);
    for (int f : flagged) {
      for (int g = std::max(first, f - runUp); g <= f; ++g) {
        needed[static_cast<std::size_t>(g - first)] = true;
      }
      wanted[static_cast<std::size_t>(f - first)] = true;
    }
    std::vector<SimulationRun> expected;
    for (int i = 0; i < span; ++i) {
      if (!needed[static_cast<std::size_t>(i)]) {
        continue;
      }
      if (expected.empty() || !needed[static_cast<std::size_t>(i - 1)]) {
        expected.push_back({first + i, first + i, 0});
      }
      expected.back().to = first + i;
      expected.back().wanted += wanted[static_cast<std::size_t>(i)] ? 1 : 0;
    }
    const std::vector<SimulationRun> runs = simulationRuns(flagged, first, runUp);
    ASSERT_EQ(runs.size(), expected.size()) << "trial " << trial;
    for (std::size_t r = 0; r < runs.size(); ++r) {
      EXPECT_EQ(runs[r].from, expected[r].from) << "trial " << trial << " run " << r;
      EXPECT_EQ(runs[r].to, expected[r].to) << "trial " << trial << " run " << r;
      EXPECT_EQ(runs[r].wanted, expected[r].wanted) << "trial " << trial << " run " << r;
    }
  }
  // A hand example: 30-32 and 60 with a run-up of 20 from frame 1: 10-32, then 40-60; 40-41
  // touching 33 would merge.
  const std::vector<SimulationRun> two = simulationRuns({30, 31, 32, 60}, 1, 20);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[0].from, 10);
  EXPECT_EQ(two[0].to, 32);
  EXPECT_EQ(two[0].wanted, 3);
  EXPECT_EQ(two[1].from, 40);
  EXPECT_EQ(two[1].wanted, 1);
  EXPECT_EQ(simulationRuns({30, 31, 32, 53}, 1, 20).size(), 1u);
  EXPECT_TRUE(simulationRuns({}, 1).empty());
  expectThrows([&] { simulationRuns({5, 5}, 1); }, ErrorCode::kInternal, "ascending");
}

}  // namespace
}  // namespace drivenshape
