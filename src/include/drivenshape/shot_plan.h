// SPDX-License-Identifier: Apache-2.0
#pragma once

// The shot planner: which driver frames an Evaluator must see, in which calls, so that every
// frame is the bake's whichever tool produced it and however the user got to it. The CLI bake,
// the Python module's evaluate_cache (and the USD bake on it), the Blender add-on's bake and
// its live mode all ask it; none of them plans batches, gaps, history or warm-up itself.
//
//   ShotPlanSettings plan = shotPlanSettings(evaluator, kDefaultBatchFrames,
//                                            kDefaultTemporalWarmup);
//   for (const BatchPlan& batch : planShot(frames, driver.frames(), plan)) {
//     evaluator.resetTemporalBound();
//     std::vector<int> solve = batch.solveFrames();  // read these driver frames
//     evaluator.evaluate(solve.size(), solve.data(), driver, cloth, records,
//                        batch.warmup.size());       // cloth of batch.frames
//   }
//
// Why the frames before a batch matter: the pose model reads each frame's earlier frames
// (Evaluator::historyFrames: velocity and history), and the temporal bound (QP weights,
// maxWeightChange > 0) ties each frame's weights to the frame solved before it. A frame whose
// earlier frames the source does not hold uses the earliest it has (Evaluator::evaluate).

#include <cstddef>
#include <vector>

#include <drivenshape/bake_options.h>

namespace drivenshape {

class Evaluator;

/// What decides the batches of a shot.
struct ShotPlanSettings {
  /// Most output frames per batch (>= 1). With the temporal bound the cloth depends on it (the
  /// bound restarts at every batch); without, it only bounds memory.
  int batch = kDefaultBatchFrames;
  /// Earlier frames the evaluator reads before each frame (Evaluator::historyFrames, >= 0).
  int historyFrames = 0;
  /// Whether the settings run the temporal bound (EvaluatorSettings::maxWeightChange > 0).
  bool temporalBound = false;
  /// Frames solved before each batch to settle the bound (>= 0); used only with temporalBound.
  int temporalWarmup = kDefaultTemporalWarmup;

  /// Frames before a batch's first frame that are evaluated first and dropped:
  /// max(temporalBound ? temporalWarmup : 0, historyFrames).
  int warmupFrames() const;
};

/// The plan settings of `evaluator`: its history frames; the temporal warm-up only when its
/// settings use the bound; `batch` lowered (never below 1) so that a batch's frame blocks stay
/// within kBatchMemoryBudget, except with the bound, where the cloth depends on it. Throws
/// Error(kUsage) naming the value when batch < 1 or temporalWarmup < 0.
ShotPlanSettings shotPlanSettings(const Evaluator& evaluator, int batch, int temporalWarmup);

/// One call of the evaluator: reset its temporal state (when `restart`), evaluate the warm-up
/// frames and then the output frames, keep the output frames' cloth.
struct BatchPlan {
  /// Driver frames evaluated before `frames` and dropped (ascending; the source's frames in
  /// [frames[0] - warmupFrames, frames[0])).
  std::vector<int> warmup;
  /// The output frames, in the order they were asked for.
  std::vector<int> frames;
  /// Where frames[0] is in the frames asked for (planShot), 0 for playback.
  std::size_t first = 0;
  /// Reset the evaluator's temporal state (Evaluator::resetTemporalBound) before this batch:
  /// every batch of planShot; a playback frame that continues the frame before, not.
  bool restart = true;

  /// warmup then frames: the driver frames to read, in the order the evaluator takes them.
  std::vector<int> solveFrames() const;
};

/// The batches of `frames` (any order; repeats allowed) from a driver source that holds
/// `available` (any order; the frames asked for need not be among them, a caller reading them
/// from the source checks that). A batch starts at the first frame, after `settings.batch`
/// frames and, when the evaluator reads history, wherever the next frame is not the one after
/// the frame before (a gap, a repeat or a step back), so that a frame's history is in its own
/// batch or its warm-up: a resume, a stepped, reversed or partial bake then equals the whole
/// bake. Throws Error(kUsage) naming the setting when the settings are out of range.
std::vector<BatchPlan> planShot(const std::vector<int>& frames, const std::vector<int>& available,
                                const ShotPlanSettings& settings);

/// The plan of a timeline played, scrubbed and jumped through one frame at a time (the
/// add-on's live mode), whose every frame is the frame of a bake. A frame right after the one
/// before continues the evaluator's state (no warm-up, nothing read twice), unless a bake
/// from the frame the run started at would start a batch there (with the temporal bound, every
/// `batch` frames); any other frame (a jump, a step back, the same frame again) starts a batch
/// with its warm-up. Frame f of a run started at frame a is then frame f of a bake of a..f.
class PlaybackPlanner {
 public:
  explicit PlaybackPlanner(const ShotPlanSettings& settings);

  /// The batch that evaluates `frame` next, its warm-up from `available` (the frames the
  /// driver source holds; `frame` need not be one of them). Assumes the caller evaluates it:
  /// call reset() when it did not, or when the evaluator was used for something else.
  BatchPlan next(int frame, const std::vector<int>& available);
  /// Forgets the run: the next frame starts a batch.
  void reset();

  const ShotPlanSettings& settings() const { return mSettings; }

 private:
  ShotPlanSettings mSettings;
  bool mRunning = false;
  int mRunStart = 0;  ///< the first frame of the current run of consecutive frames
  int mLast = 0;      ///< the frame planned last
};

}  // namespace drivenshape
