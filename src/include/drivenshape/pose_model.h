// SPDX-License-Identifier: Apache-2.0
#pragma once

// The pose model (issue 17): the rest binding plus a learned correction of the local-frame
// offsets, fitted over the whole reference clip. The driver's pose is read from the mesh alone:
// the driver is split into rigid parts (found from how its vertices move across the reference
// clip, or given by a rig's skin weights), each part's rotation is fitted per frame, and the
// features are the joint rotations (each part relative to its parent part, the root part's up
// axis), their change over the last frames (velocity) and their difference from the recent
// average (history, for hysteresis). Kernel ridge regression (linear + Gaussian kernel, zero
// prior mean, so a pose far from the reference clip falls back to the plain binding) maps them
// to the offsets; the offsets are kept as a low-rank basis, so a frame is the blend of the rest
// offsets and `rank` basis shapes, in the local frames of the rest binding, like any other
// local blend. The Gaussian process variance of the same kernel measures how far a pose is
// from the reference clip; calibrated on the clip's own cross-validation it predicts the
// frame's error (the coverage verdict).

#include <algorithm>
#include <array>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <drivenshape/binding.h>
#include <drivenshape/mesh.h>

namespace drivenshape {

/// PoseModelOptions::historyFrames: the history follows the reference data (historyFramesFor).
inline constexpr int kAutoHistory = -1;
/// PoseModelOptions::clipMixtureWeight: chosen by leaving each clip out in turn.
inline constexpr double kAutoClipMixture = -1.0;
/// The weights of the per-clip models a build tries (PoseModel::clipMixtureWeight; 0 = none):
/// the model over every clip at 10, 3 and 1 times a clip model's footing. Not below 1: the
/// model over every clip has seen every frame a clip model has.
inline constexpr std::array<double, 4> kClipMixtureWeights = {0.0, 10.0, 3.0, 1.0};
/// The bake's default coverage tolerance, a share of the cloth's rest bounding-box diagonal.
inline constexpr double kDefaultCoverageShare = 0.02;
/// The tolerances (shares of that diagonal) `db build` states its verdict's outlook at.
inline constexpr std::array<double, 4> kVerdictOutlookShares = {0.01, 0.015, 0.02, 0.03};

struct PoseModelOptions {
  /// Rigid parts of the driver to find; 0 = found from the clip (findRigidParts, 2..8).
  int parts = 0;
  /// A rig's parts instead: the part of every driver vertex (e.g. the bone of largest skin
  /// weight) and the parent part of each (-1 for the root). Empty = found from the clip.
  std::vector<int> partOf;
  std::vector<int> parentOf;
  /// The up axis of the scene (gravity pulls along -up); the root part's features.
  std::array<double, 3> up = {0.0, 0.0, 1.0};
  /// Frames back for the velocity feature (0 = off) and frames averaged for the history
  /// feature (0 = off; kAutoHistory: historyFramesFor). Both need earlier driver frames
  /// (the shot planner reads them from the cache before a chunk's first frame).
  int velocityLag = 3;
  int historyFrames = kAutoHistory;
  /// The weight of the sibling features (PoseModel::siblingWeight): each pair of parts with the
  /// same parent (two thighs, two upper arms) also gives its relative rotation, times this
  /// weight; 0 = off. A rig without such pairs stores 0.
  double siblingWeight = 0.5;
  /// Basis shapes kept (the rank of the correction; at most the clip's frame count).
  int rank = 64;
  /// Frames of each reference clip in the order the frames are given (their sum is the frame
  /// count; empty = one clip). With two or more the fit also measures what each clip adds
  /// (PoseModel::clipErrors).
  std::vector<int> clipSizes;
  /// The per-clip models' weight (PoseModel::clipMixtureWeight) with two or more clips:
  /// kAutoClipMixture = with three or more clips, the weight of kClipMixtureWeights that
  /// predicts each clip left out in turn best, kept when at least 1% better than the model over
  /// every clip alone; 0 = none; > 0 = this weight.
  double clipMixtureWeight = kAutoClipMixture;
  /// The share of frames the coverage verdict's bound is calibrated to hold for (PoseModel::
  /// verdictMargin), in (0, 1).
  double verdictLevel = 0.92;
  /// Host threads (0 = all cores). The result does not depend on it.
  int threads = 0;
};

/// What one reference clip adds to a pose model fitted over several (PoseModelOptions::
/// clipSizes): mean vertex errors (scene units) on every clip's frames, each clip in turn.
struct ClipContribution {
  int frames = 0;  ///< this clip's frame count
  /// Per clip k: the cross-validated mean error on clip k's frames of the model over every
  /// clip (the same for every row) and of the same model with this clip left out (for k this
  /// clip: its frames predicted by the other clips alone). The kernel settings stay those
  /// chosen over every clip.
  std::vector<double> withAll;
  std::vector<double> without;
};

/// How well one weight of the per-clip models (PoseModel::clipMixtureWeight) predicted the
/// reference clips, each left out in turn (chooseClipMixture).
struct ClipMixtureTrial {
  double weight = 0.0;              ///< 0: the model over every clip alone
  double leftOutError = 0.0;        ///< mean vertex error over every left-out frame (scene units)
  std::vector<double> frameErrors;  ///< per reference frame, its mean vertex error left out
};

/// A fitted pose model (see above). Stored in the database file (docs/formats.md).
struct PoseModel {
  std::vector<int> partOf;  ///< Vp: the rigid part of every driver vertex
  std::vector<int> parent;  ///< per part: the parent part, -1 for the root
  /// With siblingWeight > 0 the pose features also hold, per pair of parts with the same parent
  /// (siblingPairs), their relative rotation minus the identity times this weight: what one leg
  /// does to the cloth between the legs is how it sits against the other. 0: none (no such
  /// pairs, built with it off, or a database written before 0.2.0).
  double siblingWeight = 0.0;
  std::array<double, 3> up = {0.0, 0.0, 1.0};
  int velocityLag = 0;
  int historyFrames = 0;
  /// Kernel k(x, y) = linearWeight x.y + exp(-|x - y|^2 / (2 lengthScale^2)); ridge lambda.
  double lengthScale = 1.0;
  double linearWeight = 0.0;
  double ridge = 1e-2;
  std::vector<int> frames;          ///< T reference frames fitted
  std::vector<float> features;      ///< T x featureCount()
  std::vector<float> coefficients;  ///< rank x T: basis weights c = coefficients k(x)
  std::vector<float> basis;         ///< rank x 3Vd offsets in the rest binding's local frames
  /// Per-clip models (several reference clips; clipMixtureWeight > 0): besides the model over
  /// every clip, one model per clip over that clip's frames alone, with the same kernel and
  /// basis. A frame's basis weights are the precision-weighted mean of their predictions: the
  /// model over every clip weighs clipMixtureWeight / sigma^2, clip k's 1 / sigma_k^2 (each
  /// model's posterior variance), so a pose close to one clip follows that clip's cloth where
  /// the clips put other cloth on like poses. 0: the model over every clip alone (one clip, or
  /// chosen so; databases written before 0.2.0).
  double clipMixtureWeight = 0.0;
  /// With clipMixtureWeight > 0: the frames of each clip, in `frames` order (their sum is the
  /// frame count), and each clip's coefficients, rank x T: column f belongs to the model of
  /// f's clip (c_k(x) = its columns times k(x) over its frames).
  std::vector<int> clipSizes;
  std::vector<float> clipCoefficients;
  /// The weights tried at build, with their left-out errors (chooseClipMixture). Not stored in
  /// the database file.
  std::vector<ClipMixtureTrial> clipMixtureTrials;
  /// Predicted mean vertex error of a frame = errorBias + errorScale * sigma (scene units), with
  /// sigma the kernel's posterior standard deviation; fitted on the clip's cross-validation
  /// (fitErrorLine: both non-negative; a database written before that may hold a negative
  /// bias, and predictedError() clamps at 0).
  double errorBias = 0.0;
  double errorScale = 0.0;
  /// The coverage verdict's bound, split-conformal on the held-out reference frames: a frame is
  /// called covered at tolerance tau when errorBound(sigma) = predictedError(sigma) +
  /// verdictMargin <= tau. verdictMargin is the ceil((n + 1) verdictLevel)-th smallest of the n
  /// reference frames' held-out error minus predicted error (the largest when that is past n),
  /// so that on frames like the held-out reference frames the true error is within the bound at
  /// least verdictLevel of the time. Held out: by the 5-fold cross-validation with one
  /// reference clip; with several, each frame's whole clip left out (leftOutErrors). Level 0
  /// (databases written before 0.2.0): margin 0, the bound is the predicted error itself.
  double verdictLevel = 0.0;
  double verdictMargin = 0.0;  ///< scene units
  /// Cross-validated mean vertex error over the reference clip (scene units) and, for scale,
  /// that of the plain binding.
  double crossValidationError = 0.0;
  double bindingError = 0.0;
  /// Per reference frame (in `frames` order), its cross-validated mean vertex error: what the
  /// build log breaks down by clip, and its posterior deviation in its fold. Not stored in the
  /// database file (empty once loaded).
  std::vector<double> frameErrors;
  std::vector<double> frameSigmas;
  /// With several reference clips: what each added (ClipContribution, in clip order). Not
  /// stored in the database file.
  std::vector<ClipContribution> clipErrors;
  /// With several reference clips: every reference frame's mean vertex error and posterior
  /// deviation when its whole clip is left out (predicted by the other clips). The verdict is
  /// calibrated on these then. Not stored in the database file.
  std::vector<double> leftOutErrors;
  std::vector<double> leftOutSigmas;

  bool empty() const { return frames.empty(); }
  /// The predicted mean vertex error at posterior deviation `sigma`: errorBias + errorScale
  /// sigma, never below 0.
  double predictedError(double sigma) const {
    return std::max(0.0, errorBias + errorScale * sigma);
  }
  /// The verdict's bound on the mean vertex error at posterior deviation `sigma`:
  /// predictedError(sigma) + verdictMargin.
  double errorBound(double sigma) const { return predictedError(sigma) + verdictMargin; }
  /// The smallest bound the verdict can give a frame, errorBound(0): at a coverage tolerance
  /// below it every frame is flagged for simulation.
  double smallestErrorBound() const { return errorBound(0.0); }
  int partCount() const { return static_cast<int>(parent.size()); }
  /// The pairs of parts (a < b) with the same parent, in order of a then b.
  std::vector<std::array<int, 2>> siblingPairs() const {
    std::vector<std::array<int, 2>> pairs;
    for (int a = 0; a < partCount(); ++a) {
      for (int b = a + 1; b < partCount(); ++b) {
        if (parent[static_cast<std::size_t>(a)] >= 0 &&
            parent[static_cast<std::size_t>(a)] == parent[static_cast<std::size_t>(b)]) {
          pairs.push_back({a, b});
        }
      }
    }
    return pairs;
  }
  /// Features of one pose: 9 per part with a parent (its rotation relative to the parent's,
  /// minus the identity), 3 per root (the up axis in the root's frame, minus up); with
  /// siblingWeight > 0, 9 per sibling pair (their relative rotation, minus the identity, times
  /// the weight).
  int poseFeatureCount() const {
    int count = 0;
    for (int p : parent) {
      count += p < 0 ? 3 : 9;
    }
    if (siblingWeight > 0.0) {
      count += 9 * static_cast<int>(siblingPairs().size());
    }
    return count;
  }
  /// The pose features, then their velocity and history when those are on.
  int featureCount() const {
    return poseFeatureCount() * (1 + (velocityLag > 0 ? 1 : 0) + (historyFrames > 1 ? 1 : 0));
  }
  int frameCount() const { return static_cast<int>(frames.size()); }
  int rank() const {
    return frames.empty() ? 0 : static_cast<int>(coefficients.size() / frames.size());
  }
  /// Earlier frames a frame's features read (0 without velocity and history).
  int historyNeeded() const {
    return velocityLag > historyFrames - 1 ? velocityLag
           : historyFrames - 1 > 0         ? historyFrames - 1
                                           : 0;
  }
};

/// The share of the reference frames whose held-out error bound (errorBound of the deviation
/// they had when held out for the verdict's calibration: their clip left out with several
/// clips, their cross-validation block with one) is within `tolerance`: what the verdict calls
/// enough on shots like them. Needs the build's held-out figures (frameSigmas, leftOutSigmas);
/// 0 for a model without them (one loaded from a file).
double heldOutEnoughShare(const PoseModel& model, double tolerance);

/// The verdict's outlook at one tolerance: `share` of the rest cloth's diagonal, `tolerance`
/// that length (scene units), `enough` heldOutEnoughShare at it.
struct VerdictOutlook {
  double share = 0.0;
  double tolerance = 0.0;
  double enough = 0.0;
};
/// The outlook at each of kVerdictOutlookShares of `cloth`'s rest diagonal: what the build
/// log's verdict line and `db build --model-json` state.
std::vector<VerdictOutlook> verdictOutlook(const PoseModel& model, const Mesh& cloth);

/// `value` (scene units) as a percentage of `cloth`'s rest bounding-box diagonal, rounded to two
/// decimals: how the verdict's tolerances and bounds are stated to people.
double percentOfDiagonal(double value, const Mesh& cloth);

/// A rig's parts (`--rig`): the JSON text of a rig file (bone_names; driver_weights, one row of
/// bone weights per driver vertex; optional bones [{name, parent}]). Every driver vertex goes to
/// its heaviest bone; the bones some vertex uses are the parts, each with the nearest ancestor
/// part as parent (-1 for none). Error(kInput) naming `source` and the problem otherwise.
void parseRigParts(const std::string& text, const std::string& source, int driverVertexCount,
                   std::vector<int>& partOf, std::vector<int>& parentOf);
/// The same from a file.
void readRigParts(const std::string& path, int driverVertexCount, std::vector<int>& partOf,
                  std::vector<int>& parentOf);

/// The error predictor's line: errorBias and errorScale of error ~ errorBias + errorScale sigma
/// over the reference frames' cross-validated mean vertex errors `error` and posterior
/// deviations `sigma` (same length, at least 2), least squares with both coefficients kept
/// non-negative, so that no pose is predicted a negative error. Error(kInput) when the lengths
/// differ or are below 2.
std::array<double, 2> fitErrorLine(const Eigen::Ref<const Eigen::VectorXd>& sigma,
                                   const Eigen::Ref<const Eigen::VectorXd>& error);

/// The split-conformal margin of the verdict's bound (PoseModel::verdictMargin): over the
/// reference frames' held-out errors and their predicted errors (same length, at least 1), the
/// ceil((n + 1) level)-th smallest error - predicted (the largest when that rank is past n),
/// never below 0. Error(kInput) when the lengths differ or are 0, or the level is not in
/// (0, 1).
double conformalMargin(const std::vector<double>& error, const std::vector<double>& predicted,
                       double level);

/// Finds `parts` rigid parts of the driver over `frameCount` frames (frame-major, V x 3 each):
/// hard assignment of every vertex to the part whose per-frame rigid motions explain its
/// trajectory best, from farthest-point seeds at rest; `parts` = 0 grows the count from 2 while
/// each leaves at most two thirds of the residual of the count kept before it, and past a count
/// that does not, tries the next once, kept when it leaves at most a third (at most 8). Sets
/// `parent` (the part that rotates least is the root; every other part hangs off the neighbour it
/// shares most edges with).
std::vector<int> findRigidParts(const Mesh& driver, const float* frames, int frameCount, int parts,
                                std::vector<int>& parent, int threads, std::ostream* log);

/// Driver frames read only for velocity and history, never fitted or evaluated: the frames a
/// cache holds just before the wanted ones (what a bake reads before each batch).
struct EarlierFrames {
  const float* driverFrames = nullptr;  ///< frames.size() x V x 3, frame-major
  std::vector<int> frames;              ///< their frame numbers
};

/// The history feature's frames for `clipCount` reference clips: options.historyFrames when it is
/// set, else (kAutoHistory) 15 with one or two clips and 30 with three or more. A longer history
/// tells takes apart that put other cloth on the same pose, but needs the data of several to be
/// learnt: chosen on the validation table (docs/validation.md: with three clips 30 frames
/// lowered the held-out error of both characters, with two only the sleeve's, with one neither).
int historyFramesFor(const PoseModelOptions& options, int clipCount);

/// Fits the pose model on reference frames: `frameCount` driver and driven frames (frame-major)
/// with their frame numbers (consecutive numbers are what velocity and history read, in these
/// frames and in `history`), and the rest binding of the driven mesh (exact closest points on
/// the rest driver). Frames of several clips go together once numbered apart
/// (referenceClipOffsets); the cross-validation folds are contiguous blocks of the frames in the
/// order given. Throws Error(kInput) naming the problem when there are too few frames or the
/// parts are degenerate.
PoseModel fitPoseModel(const Mesh& driver, const Mesh& driven, const float* driverFrames,
                       const float* drivenFrames, const std::vector<int>& frames,
                       const std::vector<SurfaceHit>& restHits, const PoseModelOptions& options,
                       std::ostream* log, const EarlierFrames& history = {});

/// Frame-number offsets that keep reference clips apart in one pose model, so that velocity and
/// history never read across clips: `ranges` holds each clip's first and last frame (history
/// frames included). The first clip keeps its numbers (offset 0); every later clip is moved by
/// the smallest positive multiple of 100000 that puts its first frame more than
/// `historyNeeded` + 1 frames after the last of every clip before it (model frame = source
/// frame + offset). Throws Error(kInput) when the numbers would leave the int range.
std::vector<int> referenceClipOffsets(const std::vector<std::array<int, 2>>& ranges,
                                      int historyNeeded);

/// Evaluates a pose model: the features of a block of frames and the basis weights and
/// predicted error of each.
class PosePredictor {
 public:
  /// Features alone need only the parts; predict() needs the fitted tables.
  PosePredictor(const PoseModel& model, const Mesh& driver);

  /// The pose features (poseFeatureCount()) of one driver frame (V x 3).
  void poseFeatures(const float* frame, double* out) const;
  /// The full features of frame i of a block from the pose features of the block's frames
  /// (count x poseFeatureCount(), frame numbers `frames`): velocity and history read the
  /// frames numbered frames[i] - 1, - 2, ... found in the block, the earliest found standing
  /// in for those before it.
  void features(const double* pose, const int* frames, int count, int i, double* out) const;
  /// The full features (frames.size() x featureCount()) of driver frames (frame-major V x 3,
  /// numbers `frames`, any order), velocity and history read from these frames and `history`
  /// sorted by frame number: what a bake computes for them. Host threads: `threads`.
  Eigen::MatrixXd blockFeatures(const float* driverFrames, const std::vector<int>& frames,
                                const EarlierFrames& history, int threads) const;
  struct Prediction {
    Eigen::VectorXd weights;  ///< rank(): the basis weights (with the per-clip models mixed in)
    double sigma = 0.0;       ///< posterior standard deviation of the model over every clip
    double predictedError = 0.0;
  };
  Prediction predict(const double* features) const;

  const PoseModel& model() const { return mModel; }

 private:
  const PoseModel& mModel;
  std::vector<std::vector<int>> mPartVertices;
  std::vector<Eigen::Vector3d> mRestCenters;
  std::vector<Eigen::Matrix3Xd> mRestCentered;
  std::vector<std::array<int, 2>> mSiblingPairs;  ///< PoseModel::siblingPairs()
  /// PoseModel::poseFeatureCount() and featureCount(), counted once rather than per frame.
  int mPoseFeatureCount = 0;
  int mFeatureCount = 0;
  Eigen::MatrixXd mFeatures;       ///< T x d (double)
  Eigen::MatrixXd mCoefficients;   ///< rank x T
  Eigen::MatrixXd mKernelInverse;  ///< (K + lambda I)^-1, for the variance
  /// The per-clip models (PoseModel::clipMixtureWeight > 0): each clip's rows of the reference
  /// frames, coefficients (rank x count) and (K_k + lambda I)^-1.
  struct ClipModel {
    int begin = 0, count = 0;
    Eigen::MatrixXd coefficients;
    Eigen::MatrixXd kernelInverse;
  };
  std::vector<ClipModel> mClipModels;
};

/// A reference frame worth simulating (suggestFrames).
struct FrameSuggestion {
  int candidate = -1;  ///< row of the candidate features
  /// The predicted error (PoseModel::predictedError) of the shot frames' mean deviation before
  /// this frame is added (with the suggestions before it) and after (scene units): their mean
  /// predicted error, the line being non-negative.
  double errorBefore = 0.0;
  double errorAfter = 0.0;
  /// The same for the mean posterior deviation sigma.
  double sigmaBefore = 0.0;
  double sigmaAfter = 0.0;
};

/// Which candidate poses, simulated and added to the reference frames, would most lower the
/// predicted error of the shot poses: greedy Gaussian-process variance reduction. Each step
/// adds the candidate whose addition (an observation with the model's ridge as noise, the same
/// kernel) leaves the smallest sum over shot frames of the posterior deviation sigma, which is
/// the smallest sum of predicted errors errorBias + errorScale sigma whenever errorScale > 0;
/// the posterior is updated by a rank-one step, never refitted. Ties go to the earlier
/// candidate, so the result is deterministic and does not depend on `threads`.
///
///   candidates  C x featureCount()   (PosePredictor::blockFeatures of the candidate clip)
///   shots       S x featureCount()   (the same of the shots' frames)
///
/// Returns min(count, C) suggestions in the order picked (C x S doubles of working memory).
/// Error(kUsage) when count < 1; Error(kInput) when the model is not fitted or a matrix has
/// the wrong width or no rows.
std::vector<FrameSuggestion> suggestFrames(const PoseModel& model,
                                           const Eigen::Ref<const Eigen::MatrixXd>& candidates,
                                           const Eigen::Ref<const Eigen::MatrixXd>& shots,
                                           int count, int threads);

}  // namespace drivenshape
