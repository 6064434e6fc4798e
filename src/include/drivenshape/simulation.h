// SPDX-License-Identifier: Apache-2.0
#pragma once

// Simulating what a bake's verdict flags (`drivenshape simulate`, issue 44): the plan of the
// windows a cloth solver runs, warm-started from the bake, and the splice of their frames back
// into the baked sequence. Both are pure functions of their inputs (no threads, no files but
// the plan's own reader and writer), so a farm's splice task and a local run give the same
// bytes.
//
//   const SimulationPlan plan = planSimulation(readBakeReportCoverage("out/x.report.json"), {});
//   // ... a solver simulates each window's frames warmupFrom..to ...
//   const SplicedShot shot = spliceSimulation(plan, vertexCount, baked, simulated);

#include <string>
#include <vector>

#include <drivenshape/bake_options.h>
#include <drivenshape/coverage_check.h>
#include <drivenshape/point_cache.h>

namespace drivenshape {

/// The windows to simulate for a shot, and the settings they were planned and are spliced with.
struct SimulationPlan {
  std::string report;          ///< the bake report planned from, as given (for messages)
  SimulationOptions settings;  ///< warm-up, merge gap, goal strength, seam, carry, from start
  int first = 0;               ///< the shot's first frame
  int last = 0;                ///< its last frame: the shot is every frame first..last
  /// In frame order; between two windows at least one frame is simulated by neither.
  std::vector<SimulationWindow> windows;
  /// Frames the solver runs over all windows (warm-ups included).
  int simulatedFrames() const;
};

/// The plan for the frames `report` holds (every frame from its first to its last: the frames
/// of one bake; a frame without a prediction counts as not flagged) and its flagged frames:
/// simulationWindows(flagged, first, warmup, mergeGap), or with `fromStart` one window from the
/// shot's first frame handing back its first to its last flagged frame. No window when nothing
/// is flagged. Error(kUsage) for settings out of range (checkSimulationSettings);
/// Error(kInput) naming the report when it holds no frame, misses a frame between its first and
/// last (naming it: give the report of one whole bake, chunks merged) or predicts none (a bake
/// without the pose model).
SimulationPlan planSimulation(const BakeReportCoverage& report, const SimulationOptions& settings);

/// The plan as JSON text (docs/formats.md, "Simulation plan"): format
/// "drivenshape-simulation-plan", version 1, report, settings (by the settings table's keys),
/// frames {first, last}, windows [{warmup_from, from, to}], simulated_frames.
std::string simulationPlanJson(const SimulationPlan& plan);
/// The plan simulationPlanJson wrote, back (its windows' `wanted` is 0: the JSON does not hold
/// it). Error(kInput) naming `source` and the field for text that is not such a plan: another
/// format or version, a setting missing, unknown or out of range, windows out of order,
/// overlapping, touching or outside the frames, a simulated_frames that is not their sum.
SimulationPlan parseSimulationPlan(const std::string& text, const std::string& source);
/// The same from a file.
SimulationPlan readSimulationPlan(const std::string& path);

/// Where a frame of a spliced shot comes from.
enum class FrameSource { kBaked, kSimulated, kBlended };
/// "baked", "simulated", "blended".
const char* frameSourceName(FrameSource source);

/// A shot with its simulated windows spliced in: every frame first..last of the plan.
struct SplicedShot {
  std::vector<float> positions;      ///< frame-major, 3 * vertexCount floats per frame
  std::vector<FrameSource> sources;  ///< one per frame
};

/// Splices the simulated windows into the baked frames. `baked` holds every frame of the plan
/// (first..last, 3V floats each); `simulated[w]` holds window w's frames warmupFrom..to. With
/// B(f) the baked and S(f) the simulated positions of frame f (per coordinate, in double, each
/// result rounded to float), for each window [warmupFrom, from, to] of the plan:
///
///   from <= f <= to:            out(f) = S(f)                                  (simulated)
///   seam, k = 1..s:             f = from - s - 1 + k, w = k / (s + 1),
///                               out(f) = B(f) + w (S(f) - B(f))                (blended)
///                               where s = min(seam, from - warmupFrom): the seam lies in
///                               the warm-up; its weights rise linearly, never 0 or 1
///   carry, k = 1..c:            f = to + k, r = S(to) - B(to),
///                               out(f) = B(f) + (1 - k / (carry + 1)) r         (blended)
///                               stopping before the next window's seam and at the last frame
///   every other frame:          out(f) = B(f)                                  (baked)
///
/// Error(kUsage) when an array's size is not the plan's (naming it and both sizes) or the
/// vertex count is below 1; Error(kNumerical) for a simulated position that is not finite
/// (naming the window, frame and vertex).
SplicedShot spliceSimulation(const SimulationPlan& plan, int vertexCount,
                             const std::vector<float>& baked,
                             const std::vector<std::vector<float>>& simulated);

// ---- Files: what `drivenshape simulate` and a farm's tasks read and write ----------------

/// The header of the bake's first frame (its vertex count, topology, width, compression, fps),
/// after checking that the point-cache EXR sequence `bakePattern` holds every frame of the plan,
/// complete and of one vertex count and topology (checkPointCacheExrSequence). Error(kInput)
/// naming the file and the frame that is missing or does not match.
ExrPointCacheInfo checkSimulationBake(const SimulationPlan& plan, const std::string& bakePattern);

/// Why the simulated frames of `window` in the sequence `pattern` (warmupFrom..to) cannot be
/// kept, or "" when every one is a complete point-cache EXR of `vertexCount` vertices (a rerun
/// keeps such a window instead of simulating it again).
std::string simulatedWindowProblem(const SimulationWindow& window, const std::string& pattern,
                                   int vertexCount);

/// A hash (16 hex digits) of the bytes of the bake's files `bakePattern` of frames first..last:
/// what a window simulated from those frames records, so that it is kept only while the bake is
/// the same (a new bake under the same name simulates again). Error(kInput) naming a file that
/// cannot be read.
std::string bakeFramesStamp(const std::string& bakePattern, int first, int last);

/// The splice of files: reads the plan's frames of the bake `bakePattern` and each window's
/// frames warmupFrom..to of `windowPatterns[w]`, splices them (spliceSimulation) and writes every
/// frame first..last to `outputPattern` (each file atomically, with the bake's width,
/// compression, topology hash and fps, and its source in the header attribute `dsSource`).
/// Returns the splice. Error(kInput) naming the file and frame that cannot be read or does not
/// match the bake's vertex count; Error(kUsage) when the patterns are not one per window.
SplicedShot spliceSimulationFiles(const SimulationPlan& plan, const std::string& bakePattern,
                                  const std::vector<std::string>& windowPatterns,
                                  const std::string& outputPattern);

/// The report of a splice (docs/formats.md, "Simulate report"): format
/// "drivenshape-simulate-report", version 1, the plan (simulationPlanJson's object), frames
/// [{frame, source}] with one source per frame first..last, and `seconds`. Error(kUsage) when
/// `sources` does not hold one per frame of the plan.
std::string simulateReportJson(const SimulationPlan& plan, const std::vector<FrameSource>& sources,
                               double seconds);

}  // namespace drivenshape
