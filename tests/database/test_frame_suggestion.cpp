// SPDX-License-Identifier: Apache-2.0
// Which frames to simulate next (issue 17, `db build --suggest`): the greedy variance reduction
// with rank-one updates against a brute force that refits the posterior by direct inversion,
// on the sample's pose model and its test clip.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <vector>

#include <drivenshape/database.h>
#include <drivenshape/error.h>
#include <drivenshape/pose_model.h>

#include "bake_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using testing::sample;

/// The sample's database with the pose model, built once.
const Database& modelDatabase() {
  static const Database db = testing::buildSample(30, {}, true);
  return db;
}

/// Features of frames of a sample cache, velocity and history read from its earlier frames.
MatrixXd cacheFeatures(const std::string& name, const std::vector<int>& frames) {
  const Database& db = modelDatabase();
  const PosePredictor predictor(db.poseModel, db.driverMesh);
  const auto cache = openPointCache(sample(name));
  std::vector<int> earlierNumbers;
  for (int f = 1; f < frames.front(); ++f) {
    earlierNumbers.push_back(f);
  }
  const std::vector<float> driver = readFrames(*cache, frames);
  const std::vector<float> earlierDriver = readFrames(*cache, earlierNumbers);
  EarlierFrames earlier;
  earlier.driverFrames = earlierDriver.data();
  earlier.frames = earlierNumbers;
  return predictor.blockFeatures(driver.data(), frames, earlier, 1);
}

/// The kernel as docs/method.md states it: a x.y + exp(-|x - y|^2 / 2 l^2).
double kernel(const PoseModel& m, const VectorXd& x, const VectorXd& y) {
  return m.linearWeight * x.dot(y) +
         std::exp(-(x - y).squaredNorm() / (2.0 * m.lengthScale * m.lengthScale));
}

/// Brute force: the sum over shots of the posterior deviation once `observed` rows (the model's
/// reference features, then added candidates) are observed with noise = the ridge, by direct
/// inversion of the kernel matrix.
double sumOfSigma(const PoseModel& m, const MatrixXd& observed, const MatrixXd& shots) {
  const Eigen::Index n = observed.rows();
  MatrixXd k(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      k(i, j) = kernel(m, observed.row(i), observed.row(j)) + (i == j ? m.ridge : 0.0);
    }
  }
  const MatrixXd inverse = k.inverse();
  double sum = 0.0;
  for (Eigen::Index s = 0; s < shots.rows(); ++s) {
    VectorXd ks(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      ks[i] = kernel(m, observed.row(i), shots.row(s));
    }
    const double variance = kernel(m, shots.row(s), shots.row(s)) - ks.dot(inverse * ks);
    sum += std::sqrt(std::max(0.0, variance));
  }
  return sum;
}

MatrixXd referenceFeatures(const PoseModel& m) {
  return Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
             m.features.data(), m.frameCount(), m.featureCount())
      .cast<double>();
}

TEST(FrameSuggestion, RankOneGreedyPicksWhatDirectInversionPicks) {
  const PoseModel& model = modelDatabase().poseModel;
  ASSERT_FALSE(model.empty());
  const MatrixXd candidates = cacheFeatures("test.driver.pc2", testing::frameRange(1, 48));
  const MatrixXd shots = cacheFeatures("test.driver.pc2", testing::frameRange(25, 48));
  const int count = 6;
  const std::vector<FrameSuggestion> greedy = suggestFrames(model, candidates, shots, count, 0);
  ASSERT_EQ(greedy.size(), static_cast<std::size_t>(count));

  // The brute force: at each step every remaining candidate appended, the posterior refitted.
  MatrixXd observed = referenceFeatures(model);
  std::vector<bool> taken(static_cast<std::size_t>(candidates.rows()), false);
  const double s = static_cast<double>(shots.rows());
  double before = sumOfSigma(model, observed, shots) / s;
  const double tol = testing::kPosteriorRelTol;
  for (int step = 0; step < count; ++step) {
    int best = -1;
    double bestSum = std::numeric_limits<double>::infinity(), secondSum = bestSum;
    for (Eigen::Index c = 0; c < candidates.rows(); ++c) {
      if (taken[static_cast<std::size_t>(c)]) {
        continue;
      }
      MatrixXd with(observed.rows() + 1, observed.cols());
      with << observed, candidates.row(c);
      const double sum = sumOfSigma(model, with, shots);
      if (sum < bestSum) {
        secondSum = bestSum;
        bestSum = sum;
        best = static_cast<int>(c);
      } else if (sum < secondSum) {
        secondSum = sum;
      }
    }
    // The pick is only well defined if the runner-up is farther than the tolerance.
    ASSERT_GT(secondSum - bestSum, tol * bestSum) << "step " << step << ": a near tie";
    EXPECT_EQ(greedy[step].candidate, best) << "step " << step;
    const double after = bestSum / s;
    EXPECT_NEAR(greedy[step].sigmaBefore, before, tol * before) << "step " << step;
    EXPECT_NEAR(greedy[step].sigmaAfter, after, tol * after) << "step " << step;
    EXPECT_NEAR(greedy[step].errorAfter, model.errorBias + model.errorScale * after,
                tol * std::abs(greedy[step].errorAfter))
        << "step " << step;
    taken[static_cast<std::size_t>(best)] = true;
    MatrixXd grown(observed.rows() + 1, observed.cols());
    grown << observed, candidates.row(best);
    observed = grown;
    before = after;
  }
}

TEST(FrameSuggestion, TheFirstBeforeIsTheModelsOwnPrediction) {
  const Database& db = modelDatabase();
  const PosePredictor predictor(db.poseModel, db.driverMesh);
  const MatrixXd candidates = cacheFeatures("test.driver.pc2", testing::frameRange(1, 10));
  const MatrixXd shots = cacheFeatures("test.driver.pc2", testing::frameRange(20, 48));
  double error = 0.0;
  for (Eigen::Index s = 0; s < shots.rows(); ++s) {
    const VectorXd row = shots.row(s).transpose();
    error += predictor.predict(row.data()).predictedError;
  }
  error /= static_cast<double>(shots.rows());
  const std::vector<FrameSuggestion> out = suggestFrames(db.poseModel, candidates, shots, 3, 0);
  EXPECT_NEAR(out[0].errorBefore, error, testing::kPosteriorRelTol * error);
  for (std::size_t i = 0; i < out.size(); ++i) {
    EXPECT_LE(out[i].errorAfter, out[i].errorBefore) << "an observation never adds variance";
    if (i > 0) {
      EXPECT_EQ(out[i].errorBefore, out[i - 1].errorAfter);
    }
  }
}

TEST(FrameSuggestion, AShotPoseAmongTheCandidatesIsSuggestedFirst) {
  const PoseModel& model = modelDatabase().poseModel;
  const MatrixXd test = cacheFeatures("test.driver.pc2", testing::frameRange(1, 48));
  // Among poses the model has seen (its own reference frames), the shot's pose lowers its
  // deviation most. (Not among any poses: by Cauchy-Schwarz a pose correlated with the shot's
  // but of larger prior variance, e.g. further along the linear kernel, can lower it more, and
  // on the test clip frame 13 does for frame 12.)
  const MatrixXd seen = referenceFeatures(model);
  for (int frame : {12, 30, 45}) {
    const MatrixXd shot = test.row(frame - 1);
    MatrixXd candidates(seen.rows() + 1, seen.cols());
    candidates << seen.topRows(20), shot, seen.bottomRows(seen.rows() - 20);
    const std::vector<FrameSuggestion> out = suggestFrames(model, candidates, shot, 1, 0);
    EXPECT_EQ(out[0].candidate, 20) << "frame " << frame;
    EXPECT_LT(out[0].sigmaAfter, out[0].sigmaBefore) << "frame " << frame;
  }
}

TEST(FrameSuggestion, DeterministicWhateverTheThreadsAndClippedToTheCandidates) {
  const PoseModel& model = modelDatabase().poseModel;
  const MatrixXd candidates = cacheFeatures("test.driver.pc2", testing::frameRange(1, 48));
  const MatrixXd shots = cacheFeatures("test.driver.pc2", testing::frameRange(10, 40));
  const std::vector<FrameSuggestion> one = suggestFrames(model, candidates, shots, 8, 1);
  const std::vector<FrameSuggestion> four = suggestFrames(model, candidates, shots, 8, 4);
  ASSERT_EQ(one.size(), four.size());
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i].candidate, four[i].candidate);
    EXPECT_EQ(one[i].errorAfter, four[i].errorAfter);
  }
  // More than the candidates: every candidate once.
  const std::vector<FrameSuggestion> all = suggestFrames(model, candidates.topRows(5), shots, 9, 0);
  ASSERT_EQ(all.size(), 5u);
  std::vector<int> picked;
  for (const FrameSuggestion& s : all) {
    picked.push_back(s.candidate);
  }
  std::sort(picked.begin(), picked.end());
  EXPECT_EQ(picked, (std::vector<int>{0, 1, 2, 3, 4}));
  testing::expectThrows([&] { suggestFrames(model, candidates, shots, 0, 0); }, ErrorCode::kUsage,
                        "at least 1");
  testing::expectThrows([&] { suggestFrames(model, candidates.leftCols(3), shots, 1, 0); },
                        ErrorCode::kInput, "columns");
  testing::expectThrows([&] { suggestFrames(PoseModel(), candidates, shots, 1, 0); },
                        ErrorCode::kInput, "fitted pose model");
}

TEST(FrameSuggestion, CachesAreReadLikeABakeAndMustMatchTheDriver) {
  const Database& db = modelDatabase();
  const auto test = openPointCache(sample("test.driver.pc2"));
  const auto cloth = openPointCache(sample("test.driven.pc2"));
  // The cache-level call reads the shot's earlier frames (1-24) for velocity and history.
  const std::vector<ReferenceSuggestion> fromCaches =
      suggestReferenceFrames(db, {test.get(), {}}, {{test.get(), testing::frameRange(25, 48)}}, 4);
  const std::vector<FrameSuggestion> direct =
      suggestFrames(db.poseModel, cacheFeatures("test.driver.pc2", testing::frameRange(1, 48)),
                    cacheFeatures("test.driver.pc2", testing::frameRange(25, 48)), 4, 0);
  ASSERT_EQ(fromCaches.size(), direct.size());
  for (std::size_t i = 0; i < direct.size(); ++i) {
    EXPECT_EQ(fromCaches[i].frame, direct[i].candidate + 1);
    EXPECT_EQ(fromCaches[i].errorAfter, direct[i].errorAfter);
  }
  testing::expectThrows(
      [&] {
        suggestReferenceFrames(db, {cloth.get(), {}}, {{test.get(), {}}}, 1);
      },
      ErrorCode::kInput, "candidate clip: driver cache '" + sample("test.driven.pc2"));
  testing::expectThrows(
      [&] {
        suggestReferenceFrames(db, {test.get(), {}}, {{test.get(), {}}, {cloth.get(), {}}}, 1);
      },
      ErrorCode::kInput, "shot 2: driver cache");
  testing::expectThrows(
      [&] {
        suggestReferenceFrames(db, {test.get(), testing::frameRange(40, 60)}, {{test.get(), {}}},
                               1);
      },
      ErrorCode::kInput, "has no frame 49");
  testing::expectThrows(
      [&] {
        suggestReferenceFrames(testing::sampleDatabase(), {test.get(), {}}, {{test.get(), {}}}, 1);
      },
      ErrorCode::kInput, "has none");
}

}  // namespace
}  // namespace drivenshape
