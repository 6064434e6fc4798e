// SPDX-License-Identifier: Apache-2.0
// The shot planner (drivenshape/shot_plan.h): batches, gaps, history and temporal warm-up, the
// one plan of every tool that evaluates a shot.

#include <drivenshape/shot_plan.h>

#include <algorithm>

#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>

namespace drivenshape {
namespace {

void checkSettings(const ShotPlanSettings& settings) {
  if (settings.batch < 1) {
    DS_THROW(kUsage, "the batch size must be at least 1 frame (got ", settings.batch, ")");
  }
  if (settings.temporalWarmup < 0) {
    DS_THROW(kUsage, "the temporal warm-up must be >= 0 frames (got ", settings.temporalWarmup,
             ")");
  }
  if (settings.historyFrames < 0) {
    DS_THROW(kUsage, "the history frames must be >= 0 (got ", settings.historyFrames, ")");
  }
}

/// The source's frames in [first - count, first), ascending; `sorted` is ascending and unique.
std::vector<int> framesBefore(const std::vector<int>& sorted, int first, int count) {
  if (count <= 0) {
    return {};
  }
  const long long from = static_cast<long long>(first) - count;
  const auto begin = std::lower_bound(
      sorted.begin(), sorted.end(), from,
      [](int frame, long long value) { return static_cast<long long>(frame) < value; });
  return std::vector<int>(begin, std::lower_bound(begin, sorted.end(), first));
}

std::vector<int> sortedUnique(std::vector<int> frames) {
  std::sort(frames.begin(), frames.end());
  frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
  return frames;
}

/// Whether `frame` is the frame after `before` (false at the end of the int range).
bool follows(int before, int frame) {
  return static_cast<long long>(frame) == static_cast<long long>(before) + 1;
}

}  // namespace

int ShotPlanSettings::warmupFrames() const {
  return std::max(temporalBound ? temporalWarmup : 0, historyFrames);
}

std::vector<int> BatchPlan::solveFrames() const {
  std::vector<int> solve = warmup;
  solve.insert(solve.end(), frames.begin(), frames.end());
  return solve;
}

ShotPlanSettings shotPlanSettings(const Evaluator& evaluator, int batch, int temporalWarmup) {
  ShotPlanSettings settings;
  settings.batch = batch;
  settings.temporalWarmup = temporalWarmup;
  settings.historyFrames = evaluator.historyFrames();
  settings.temporalBound = evaluator.settings().maxWeightChange > 0;
  checkSettings(settings);
  if (!settings.temporalBound) {
    const std::size_t perFrame = std::max<std::size_t>(1, evaluator.bytesPerFrame());
    const std::size_t fit = std::max<std::size_t>(1, kBatchMemoryBudget / perFrame);
    settings.batch = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(batch), fit));
  }
  return settings;
}

std::vector<BatchPlan> planShot(const std::vector<int>& frames, const std::vector<int>& available,
                                const ShotPlanSettings& settings) {
  checkSettings(settings);
  const int warmup = settings.warmupFrames();
  const std::vector<int> source = warmup > 0 ? sortedUnique(available) : std::vector<int>();
  const std::size_t batch = static_cast<std::size_t>(settings.batch);
  std::vector<BatchPlan> batches;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const bool gap = settings.historyFrames > 0 && i > 0 && !follows(frames[i - 1], frames[i]);
    if (batches.empty() || gap || i - batches.back().first >= batch) {
      BatchPlan next;
      next.first = i;
      next.warmup = framesBefore(source, frames[i], warmup);
      batches.push_back(std::move(next));
    }
    batches.back().frames.push_back(frames[i]);
  }
  return batches;
}

PlaybackPlanner::PlaybackPlanner(const ShotPlanSettings& settings) : mSettings(settings) {
  checkSettings(mSettings);
}

BatchPlan PlaybackPlanner::next(int frame, const std::vector<int>& available) {
  const bool consecutive = mRunning && follows(mLast, frame);
  if (!consecutive) {
    mRunStart = frame;
  }
  mRunning = true;
  mLast = frame;
  // Without the bound a batch start within a run changes nothing the evaluator's state does
  // not already hold (the history frames are the same frames); with it, the bake of the run
  // restarts the bound every `batch` frames.
  const long long index = static_cast<long long>(frame) - mRunStart;
  if (consecutive && !(mSettings.temporalBound && index % mSettings.batch == 0)) {
    BatchPlan batch;
    batch.frames = {frame};
    batch.restart = false;
    return batch;
  }
  return planShot({frame}, available, mSettings).front();
}

void PlaybackPlanner::reset() {
  mRunning = false;
}

}  // namespace drivenshape
