// SPDX-License-Identifier: Apache-2.0
// Per-clip models of the pose model (issue 30, `db build --model-per-clip`): with several
// reference clips, one kernel model per clip is mixed with the model over every clip by the
// models' posterior precisions. The tests check the mixture against the formula of
// docs/method.md computed here from the stored tables, each clip's model against the ridge fit
// of its own frames, the build's choice against its own trials and against the clip
// contributions computed apart, and the file round trip.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <vector>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include <drivenshape/database.h>
#include <drivenshape/database_build.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/pose_model.h>

#include "bake_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using testing::sample;

/// The sample's train clip plus the test clip's two halves as two more clips (three clips),
/// or plus the first half only (two), with the per-clip weight `weight` (kAutoClipMixture,
/// 0 = none, or a weight).
Database buildClips(int clips, double weight) {
  const testing::SampleClips s;
  std::vector<ReferenceClip> extra;
  if (clips >= 2) {
    extra.push_back({s.testDriver.get(), s.testDriven.get(), testing::frameRange(1, 24)});
  }
  if (clips >= 3) {
    extra.push_back({s.testDriver.get(), s.testDriven.get(), testing::frameRange(25, 48)});
  }
  DatabaseBuildOptions options;
  options.poseModel = true;
  options.model.clipMixtureWeight = weight;
  return buildDatabase(s.driver, s.driven, *s.trainDriver, *s.trainDriven, extra, options);
}

/// Row-major float table (rows x cols) as doubles.
MatrixXd table(const std::vector<float>& values, int rows, int cols) {
  return Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
             values.data(), rows, cols)
      .cast<double>();
}

/// docs/method.md's kernel: linearWeight x.y + exp(-|x - y|^2 / (2 lengthScale^2)).
double kernel(const PoseModel& m, const VectorXd& a, const VectorXd& b) {
  return m.linearWeight * a.dot(b) +
         std::exp(-(a - b).squaredNorm() / (2.0 * m.lengthScale * m.lengthScale));
}

MatrixXd gram(const PoseModel& m, const MatrixXd& rows) {
  MatrixXd k(rows.rows(), rows.rows());
  for (Eigen::Index i = 0; i < rows.rows(); ++i) {
    for (Eigen::Index j = 0; j < rows.rows(); ++j) {
      k(i, j) = kernel(m, rows.row(i).transpose(), rows.row(j).transpose());
    }
  }
  return k;
}

/// Relative tolerance of a prediction computed here with explicit inverses against the
/// library's Cholesky solves of the same double tables.
constexpr double kSolveTolerance = 1e-7;
/// Relative tolerance of coordinates rebuilt from float coefficient tables: float rounding
/// (6e-8) amplified by the condition of K + lambda I (below 1e5 on the sample).
constexpr double kRebuildTolerance = 1e-2;

TEST(ClipModels, TheMixtureIsThePrecisionWeightedMeanOfEachClipsModel) {
  const double weight = 2.0;
  const Database db = buildClips(3, weight);
  const PoseModel& m = db.poseModel;
  ASSERT_EQ(m.clipMixtureWeight, weight);
  ASSERT_EQ(m.clipSizes, (std::vector<int>{61, 24, 24}));
  const int t = m.frameCount(), r = m.rank(), d = m.featureCount();
  ASSERT_EQ(m.clipCoefficients.size(), static_cast<std::size_t>(r) * t);
  const MatrixXd x = table(m.features, t, d);
  const MatrixXd global = table(m.coefficients, r, t);
  const MatrixXd own = table(m.clipCoefficients, r, t);

  // Each clip's model is the ridge fit of its own frames: its coefficients give back the
  // coordinates the model over every clip was fitted to, on that clip's frames.
  MatrixXd kAll = gram(m, x);
  kAll.diagonal().array() += m.ridge;
  const MatrixXd coords = kAll * global.transpose();  // T x r
  std::vector<int> start = {0};
  for (int size : m.clipSizes) {
    start.push_back(start.back() + size);
  }
  for (int k = 0; k < 3; ++k) {
    const int n = start[k + 1] - start[k];
    const MatrixXd rebuilt =
        kAll.block(start[k], start[k], n, n) * own.middleCols(start[k], n).transpose();
    const MatrixXd expected = coords.middleRows(start[k], n);
    EXPECT_LT((rebuilt - expected).norm(), kRebuildTolerance * expected.norm()) << "clip " << k;
  }

  // The prediction of shot frames against the formula: each model's posterior mean and
  // variance by explicit inverses, mixed with shares weight / var for the model over every clip
  // and 1 / var_k for clip k's.
  const PosePredictor predictor(m, db.driverMesh);
  const auto shot = openPointCache(sample("test.driver.pc2"));
  const std::vector<int> frames = testing::frameRange(1, 48);
  const MatrixXd features =
      predictor.blockFeatures(readFrames(*shot, frames).data(), frames, {}, 1);
  const MatrixXd inverseAll = kAll.inverse();
  double largestShare = 0.0;
  for (int i = 0; i < 48; i += 5) {
    const VectorXd q = features.row(i).transpose();
    VectorXd kq(t);
    for (int f = 0; f < t; ++f) {
      kq[f] = kernel(m, q, x.row(f).transpose());
    }
    const double prior = m.linearWeight * q.squaredNorm() + 1.0;
    const double globalVariance = std::max(1e-12, prior - kq.dot(inverseAll * kq));
    double total = weight / globalVariance;
    VectorXd mixed = total * (global * kq);
    for (int k = 0; k < 3; ++k) {
      const int n = start[k + 1] - start[k];
      const VectorXd kk = kq.segment(start[k], n);
      const MatrixXd inverse = kAll.block(start[k], start[k], n, n).inverse();
      const double variance = std::max(1e-12, prior - kk.dot(inverse * kk));
      mixed += own.middleCols(start[k], n) * kk / variance;
      total += 1.0 / variance;
      largestShare = std::max(largestShare, 1.0 / variance / (weight / globalVariance));
    }
    mixed /= total;
    const PosePredictor::Prediction p = predictor.predict(q.data());
    EXPECT_LT((p.weights - mixed).norm(), kSolveTolerance * mixed.norm()) << "shot frame " << i + 1;
    EXPECT_NEAR(p.sigma, std::sqrt(globalVariance), kSolveTolerance * std::sqrt(globalVariance))
        << "the verdict reads the model over every clip";
  }
  EXPECT_GT(largestShare, 0.1) << "the clip models weigh in on some frame";
}

TEST(ClipModels, TheBuildKeepsThemOnlyWhenLeftOutClipsArePredictedBetter) {
  const Database db = buildClips(3, kAutoClipMixture);
  const PoseModel& m = db.poseModel;
  ASSERT_EQ(m.clipMixtureTrials.size(), kClipMixtureWeights.size());
  for (std::size_t i = 0; i < kClipMixtureWeights.size(); ++i) {
    EXPECT_EQ(m.clipMixtureTrials[i].weight, kClipMixtureWeights[i]);
  }
  // The first trial is the model over the other clips alone: the clip contributions compute the
  // same left-out predictions apart (PoseModel::clipErrors, one clip's frames each).
  ASSERT_EQ(m.clipErrors.size(), 3u);
  double frames = 0.0, sum = 0.0;
  for (std::size_t k = 0; k < 3; ++k) {
    sum += m.clipErrors[k].without[k] * m.clipErrors[k].frames;
    frames += m.clipErrors[k].frames;
  }
  EXPECT_NEAR(m.clipMixtureTrials[0].leftOutError, sum / frames, 1e-9 * sum / frames);
  const auto best = std::min_element(m.clipMixtureTrials.begin(), m.clipMixtureTrials.end(),
                                     [](const ClipMixtureTrial& a, const ClipMixtureTrial& b) {
                                       return a.leftOutError < b.leftOutError;
                                     });
  const bool better =
      best->weight > 0.0 && best->leftOutError < 0.99 * m.clipMixtureTrials[0].leftOutError;
  std::cout << "left-out mean error without the clip models " << m.clipMixtureTrials[0].leftOutError
            << ", best " << best->leftOutError << " at weight " << best->weight << "; kept "
            << m.clipMixtureWeight << "\n";
  EXPECT_EQ(m.clipMixtureWeight, better ? best->weight : 0.0);
  // The verdict is calibrated on the left-out errors of what a bake predicts.
  EXPECT_EQ(m.leftOutErrors, better ? best->frameErrors : m.clipMixtureTrials[0].frameErrors);
}

TEST(ClipModels, OneOrTwoClipsOrOffMixNothing) {
  for (const auto& [clips, weight] : std::vector<std::pair<int, double>>{
           {1, kAutoClipMixture}, {2, kAutoClipMixture}, {3, 0.0}}) {
    const PoseModel m = buildClips(clips, weight).poseModel;
    EXPECT_EQ(m.clipMixtureWeight, 0.0) << clips << " clips";
    EXPECT_TRUE(m.clipMixtureTrials.empty()) << clips << " clips";
    EXPECT_TRUE(m.clipCoefficients.empty()) << clips << " clips";
  }
}

TEST(ClipModels, TheyTravelInTheDatabaseFile) {
  const Database built = buildClips(3, 1.0);
  testing::TempDir dir;
  saveDatabase(dir.file("clips.dsdb"), built);
  const Database loaded = loadDatabase(dir.file("clips.dsdb"));
  EXPECT_EQ(loaded.poseModel.clipMixtureWeight, 1.0);
  EXPECT_EQ(loaded.poseModel.clipSizes, built.poseModel.clipSizes);
  EXPECT_EQ(loaded.poseModel.clipCoefficients, built.poseModel.clipCoefficients);
  EXPECT_EQ(loaded.contentHash(), built.contentHash());
  Database without = built;
  without.poseModel.clipMixtureWeight = 0.0;
  EXPECT_NE(without.contentHash(), built.contentHash()) << "the hash covers the clip models";

  const auto shot = openPointCache(sample("test.driver.pc2"));
  const std::vector<int> frames = testing::frameRange(1, 48);
  const std::vector<float> pose = readFrames(*shot, frames);
  testing::Backends host = testing::hostBackends();
  const EvaluatorSettings settings;
  const Evaluation a = Evaluator(built, settings, host.view()).evaluate(frames, pose);
  const Evaluation b = Evaluator(loaded, settings, host.view()).evaluate(frames, pose);
  EXPECT_EQ(a.cloth, b.cloth) << "bit for bit";
  const Evaluation c = Evaluator(without, settings, host.view()).evaluate(frames, pose);
  EXPECT_NE(a.cloth, c.cloth) << "the clip models change the bake";
  // The report's settings say so (docs/schemas/bake_report.schema.json).
  const auto described = [&](const Database& db) {
    return nlohmann::json::parse(Evaluator(db, settings, host.view()).describeSettings());
  };
  EXPECT_EQ(described(loaded)["pose_model"]["per_clip_models"],
            nlohmann::json({{"clips", 3}, {"weight", 1.0}}));
  EXPECT_FALSE(described(without)["pose_model"].contains("per_clip_models"));
}

}  // namespace
}  // namespace drivenshape
