// SPDX-License-Identifier: Apache-2.0
// `db build --suggest` (drivenshape/database.h, suggestReferenceFrames): the features of a
// candidate clip and of the shots, read as a bake reads them, handed to suggestFrames.

#include <drivenshape/database.h>

#include <ostream>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>

#include "reference_frames.h"

namespace drivenshape {
namespace {

/// The features of a clip's frames (every frame of its cache when none are given), velocity and
/// history read from the cache's earlier frames; `frames` receives the frames.
Eigen::MatrixXd clipFeatures(const PosePredictor& predictor, const Mesh& driverMesh,
                             const DriverClip& clip, const std::string& what, int threads,
                             std::vector<int>& frames) {
  if (clip.driver == nullptr) {
    DS_THROW(kUsage, what, " has no driver cache");
  }
  checkClipVertexCount(*clip.driver, driverMesh, "driver", what);
  frames = clipFrames(*clip.driver, clip.frames, what);
  const std::vector<float> driver = readFiniteFrames(*clip.driver, frames, "driver");
  const std::vector<int> earlierNumbers =
      earlierFrames(*clip.driver, frames, predictor.model().historyNeeded());
  const std::vector<float> earlierDriver = readFiniteFrames(*clip.driver, earlierNumbers, "driver");
  EarlierFrames earlier;
  earlier.driverFrames = earlierDriver.data();
  earlier.frames = earlierNumbers;
  return predictor.blockFeatures(driver.data(), frames, earlier, threads);
}

}  // namespace

std::vector<ReferenceSuggestion> suggestReferenceFrames(const Database& database,
                                                        const DriverClip& candidate,
                                                        const std::vector<DriverClip>& shots,
                                                        int count, int threads, std::ostream* log) {
  if (count < 1) {
    DS_THROW(kUsage, "the number of frames to suggest must be at least 1 (got ", count, ")");
  }
  if (database.poseModel.empty()) {
    DS_THROW(kInput,
             "suggesting reference frames needs the pose model, and this database has "
             "none; build it with --model pose from a clip of at least 10 frames");
  }
  if (shots.empty()) {
    DS_THROW(kUsage, "suggesting reference frames needs at least one shot driver cache");
  }
  const PosePredictor predictor(database.poseModel, database.driverMesh);
  std::vector<int> candidateFrames;
  const Eigen::MatrixXd candidateFeatures = clipFeatures(
      predictor, database.driverMesh, candidate, "candidate clip", threads, candidateFrames);
  std::vector<Eigen::MatrixXd> shotBlocks;
  Eigen::Index shotRows = 0;
  for (std::size_t s = 0; s < shots.size(); ++s) {
    std::vector<int> frames;
    shotBlocks.push_back(clipFeatures(predictor, database.driverMesh, shots[s],
                                      "shot " + std::to_string(s + 1), threads, frames));
    shotRows += shotBlocks.back().rows();
    if (log != nullptr) {
      *log << "shot " << s + 1 << ": '" << shots[s].driver->path() << "', frames "
           << formatFrameRange(frames) << "\n";
    }
  }
  Eigen::MatrixXd shotFeatures(shotRows, database.poseModel.featureCount());
  Eigen::Index row = 0;
  for (const Eigen::MatrixXd& block : shotBlocks) {
    shotFeatures.middleRows(row, block.rows()) = block;
    row += block.rows();
  }
  if (log != nullptr) {
    *log << "candidate clip: '" << candidate.driver->path() << "', frames "
         << formatFrameRange(candidateFrames) << "\n";
    if (count > static_cast<int>(candidateFrames.size())) {
      *log << "suggesting every one of the " << candidateFrames.size()
           << " candidate frames (asked for " << count << ")\n";
    }
  }
  const std::vector<FrameSuggestion> picks =
      suggestFrames(database.poseModel, candidateFeatures, shotFeatures, count, threads);
  std::vector<ReferenceSuggestion> out;
  for (const FrameSuggestion& pick : picks) {
    ReferenceSuggestion suggestion;
    suggestion.frame = candidateFrames[static_cast<std::size_t>(pick.candidate)];
    suggestion.errorBefore = pick.errorBefore;
    suggestion.errorAfter = pick.errorAfter;
    suggestion.sigmaBefore = pick.sigmaBefore;
    suggestion.sigmaAfter = pick.sigmaAfter;
    out.push_back(suggestion);
  }
  return out;
}

}  // namespace drivenshape
