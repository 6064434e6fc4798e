// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <drivenshape/bake_options.h>
#include <drivenshape/evaluate.h>

namespace drivenshape {

// ---- The coverage verdict of a bake, checked against a truth (`drivenshape eval --report`) ----

/// One frame of a bake report with the pose model's prediction.
struct PredictedFrame {
  int frame = 0;
  double predictedError = 0.0;  ///< predicted mean vertex error (scene units)
  bool flagged = false;         ///< predicted worse than the tolerance: simulate it
};

/// What a bake report (`bake --report`) says about coverage.
struct BakeReportCoverage {
  std::string source;                     ///< the report's path, for messages
  std::vector<PredictedFrame> predicted;  ///< the entries with a prediction, in report order
  std::vector<int> unpredicted;           ///< the frames of the entries without one
  double tolerance = -1.0;  ///< `coverage.tolerance` (scene units); -1 when nothing is predicted
  /// `coverage.level`: the share of frames the bake's error bound was calibrated to hold for; 0
  /// for a report without one (before 0.2.0).
  double level = 0.0;
  int clothVertices = -1;  ///< `database.driven_vertices`; -1 when the report states none
  std::string weights;     ///< `settings.weights` when stated (for messages), else empty
};

/// Reads the coverage part of a bake report's JSON text. Entries of `frames` without a
/// `predicted_error` (a QP bake, frames kept by --skip-existing) go to `unpredicted`.
/// Error(kInput) naming `source` for text that is not JSON, no `frames` array, a frame listed
/// twice, a prediction that is not a finite number >= 0 or has no `coverage.flagged`, or
/// predictions without a shot `coverage.tolerance`.
BakeReportCoverage parseBakeReportCoverage(const std::string& text, const std::string& source);
/// The same from a file.
BakeReportCoverage readBakeReportCoverage(const std::string& path);

/// One evaluated frame the report predicts.
struct CoverageFrame {
  int frame = 0;
  double predictedError = 0.0;  ///< the report's
  bool flagged = false;         ///< the report's
  double trueError = 0.0;       ///< the mean vertex error eval measured against the truth
};

/// The prediction against the truth over the evaluated frames the report predicts. A frame
/// is "enough" when the report does not flag it; the verdict holds when the share of those
/// frames whose true error is within the tolerance is at least the report's level (for a report
/// without a level, when their true mean error is within the tolerance).
struct CoverageCheck {
  std::vector<CoverageFrame> frames;  ///< in the order of the evaluation
  int missing = 0;                    ///< evaluated frames the report does not list
  int unpredicted = 0;                ///< evaluated frames it lists without a prediction
  double tolerance = 0.0;
  std::optional<double> spearman;  ///< rank correlation of predicted vs true error; none with
                                   ///< fewer than 2 frames or when either side is constant
  double coveredFraction = 0.0;    ///< share of `frames` that are enough
  int enough = 0;
  int flagged = 0;
  std::optional<double> enoughTrueError;   ///< true mean error over the enough frames
  std::optional<double> flaggedTrueError;  ///< true mean error over the flagged frames
  int missed = 0;                          ///< enough frames whose true error is over tolerance
  double level = 0.0;                      ///< the report's
  std::optional<double> withinShare;       ///< (enough - missed) / enough; none without enough
  std::optional<bool> verdictHolds;        ///< withinShare >= level (level 0: enoughTrueError
                                           ///< <= tolerance); none without enough frames (the
                                           ///< verdict claims nothing)
  double predictedMean = 0.0;              ///< mean of the frames' predicted errors (scene units)
  double predictedMax = 0.0;               ///< the largest predicted error
  int predictedMaxFrame = 0;               ///< the first of `frames` with it
};

/// Whether a verdict holds against the truth, from the frames it called enough: `enough` of
/// them (at least 1), `missed` of which are truly over `tolerance`, with true mean error
/// `enoughTrueError`. At `level` > 0 (the report's) it holds when at least that share of them
/// are within the tolerance; a report without a level (0, before 0.2.0) holds when their true
/// mean error is within it. What `eval --report` and the QC page both judge. Error(kInput)
/// when enough < 1, missed is outside 0..enough or level is outside [0, 1).
bool verdictHolds(int enough, int missed, double enoughTrueError, double tolerance, double level);

/// Matches the report to the bake's evaluation (its per-frame mean error). Error(kInput)
/// naming the report when it states a cloth vertex count other than the evaluation's, or
/// predicts none of the evaluated frames (with what to do).
CoverageCheck checkCoverage(const BakeReportCoverage& report, const ShotEvaluation& evaluation);

// ---- The frames to simulate, as runs a cloth simulation can be given ----

/// Frames a cloth simulation runs before the first frame it is wanted for, so that the cloth
/// has settled from its start state: the report's run_up, a simulation window's default warm-up.
constexpr int kSimulationRunUp = kDefaultSimulationWarmup;

/// One window of cloth simulation: it runs frames warmupFrom..to and hands back from..to.
struct SimulationWindow {
  int warmupFrom = 0;  ///< the first frame simulated (from the bake's cloth there)
  int from = 0;        ///< the first frame handed back: a flagged frame
  int to = 0;          ///< the last frame handed back: a flagged frame
  int wanted = 0;      ///< flagged frames in from..to (the others are gaps merged in)
};

/// The flagged frames (ascending, distinct) as simulation windows: runs of flagged frames at
/// most `mergeGap` unflagged frames apart are one window handing back their first to their last
/// frame; each window's warm-up starts `warmup` frames before its first frame, never before
/// `first` (the shot's first frame); a window whose warm-up then starts at most one frame after
/// the previous window's end is merged into it (it hands back the frames between too). In frame
/// order. Error(kInternal) when the frames are not ascending and distinct, or `warmup` or
/// `mergeGap` is negative.
std::vector<SimulationWindow> simulationWindows(const std::vector<int>& flagged, int first,
                                                int warmup, int mergeGap);

/// One simulation run: frames from..to, of which `wanted` are flagged frames.
struct SimulationRun {
  int from = 0;
  int to = 0;
  int wanted = 0;
};

/// The flagged frames (ascending, distinct) as simulation runs: the simulationWindows without
/// merging across gaps (mergeGap 0), each run from its warm-up's start to its end: each run of
/// consecutive flagged frame numbers starts `runUp` frames earlier, never before `first` (the
/// shot's first frame), and a run that then starts at most one frame after the previous run's
/// end is merged into it. In frame order. Error(kInternal) when the frames are not ascending and
/// distinct.
std::vector<SimulationRun> simulationRuns(const std::vector<int>& flagged, int first,
                                          int runUp = kSimulationRunUp);

/// Average ranks (1-based; tied values share the mean of their positions) of `values`.
/// Error(kNumerical) for a value that is not finite.
std::vector<double> averageRanks(const std::vector<double>& values);

/// Spearman's rank correlation of `x` and `y` (the Pearson correlation of their average
/// ranks), in [-1, 1]. None with fewer than 2 pairs or when either side is constant.
/// Error(kInternal) when the sizes differ; Error(kNumerical) for a value that is not finite.
std::optional<double> spearmanCorrelation(const std::vector<double>& x,
                                          const std::vector<double>& y);

}  // namespace drivenshape
