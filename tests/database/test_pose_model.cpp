// SPDX-License-Identifier: Apache-2.0
// The pose model (issue 17): rigid parts found from motion, features that are joint rotations,
// the learned correction against the simulated truth, history that chunks cannot change, the
// database round trip and the rig reader.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>

#include <drivenshape/database.h>
#include <drivenshape/database_build.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/pose_model.h>

#include "bake_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using testing::sample;
using testing::TempDir;
using PoseModelClTest = testing::BakeClTest;

/// The sample's 30-shape database with the pose model, built once.
const Database& sampleDatabase() {
  static const Database db = testing::buildSample(30, {}, true);
  return db;
}

/// Three unit cubes in a row along x (8 vertices, 12 triangles each): a chain of rigid parts.
Mesh cubeChain() {
  Mesh mesh;
  std::vector<Eigen::Vector3f> points;
  for (int c = 0; c < 3; ++c) {
    for (int i = 0; i < 8; ++i) {
      points.emplace_back(1.5f * c + (i & 1), (i >> 1) & 1, (i >> 2) & 1);
    }
  }
  mesh.positions.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i) {
    mesh.positions.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
  }
  const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                           {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
  mesh.faceStart = {0};
  for (int c = 0; c < 3; ++c) {
    for (const auto& q : quads) {
      for (int k : q) {
        mesh.faceVertices.push_back(8 * c + k);
      }
      mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
      mesh.faceGroup.push_back(0);
    }
  }
  // Bridge triangles so the cubes share edges (parts are neighbours).
  for (int c = 0; c < 2; ++c) {
    for (int k : {8 * c + 1, 8 * (c + 1) + 0, 8 * c + 3}) {
      mesh.faceVertices.push_back(k);
    }
    mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
    mesh.faceGroup.push_back(0);
  }
  mesh.groupNames = {"default"};
  mesh.triangulate();
  return mesh;
}

/// Frames of the chain: cube 0 still, cube 1 turned by `a1[f]` about z through its hinge at
/// x = 1.25, cube 2 by a further `a2[f]` about y through x = 2.75 (carried by cube 1).
std::vector<float> chainFrames(const Mesh& mesh, const std::vector<double>& a1,
                               const std::vector<double>& a2, const Eigen::Matrix3d& world) {
  std::vector<float> out;
  for (std::size_t f = 0; f < a1.size(); ++f) {
    const Eigen::Matrix3d r1 = Eigen::AngleAxisd(a1[f], Eigen::Vector3d::UnitZ()).matrix();
    const Eigen::Matrix3d r2 = Eigen::AngleAxisd(a2[f], Eigen::Vector3d::UnitY()).matrix();
    const Eigen::Vector3d h1(1.25, 0.5, 0.5), h2(2.75, 0.5, 0.5);
    for (int v = 0; v < mesh.vertexCount(); ++v) {
      Eigen::Vector3d p = mesh.positions.row(v).cast<double>().transpose();
      if (v >= 16) {
        p = h2 + r2 * (p - h2);
      }
      if (v >= 8) {
        p = h1 + r1 * (p - h1);
      }
      p = world * p;
      for (int a = 0; a < 3; ++a) {
        out.push_back(static_cast<float>(p[a]));
      }
    }
  }
  return out;
}

/// A pose model's parts for cubeChain(): one part per cube, each the child of the one before.
PoseModel chainModel() {
  PoseModel model;
  model.partOf.assign(24, 0);
  for (int v = 8; v < 24; ++v) {
    model.partOf[v] = v < 16 ? 1 : 2;
  }
  model.parent = {-1, 0, 1};
  return model;
}

TEST(PoseModel, RigidPartsOfAnArticulatedChainAreItsCubes) {
  const Mesh mesh = cubeChain();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(-1.2, 1.2);
  std::vector<double> a1(40), a2(40);
  for (int f = 0; f < 40; ++f) {
    a1[f] = angle(rng);
    a2[f] = angle(rng);
  }
  const std::vector<float> frames = chainFrames(mesh, a1, a2, Eigen::Matrix3d::Identity());
  std::vector<int> parent;
  const std::vector<int> partOf = findRigidParts(mesh, frames.data(), 40, 0, parent, 1, nullptr);
  ASSERT_EQ(parent.size(), 3u) << "three rigid bodies, three parts";
  for (int c = 0; c < 3; ++c) {
    const std::set<int> parts(partOf.begin() + 8 * c, partOf.begin() + 8 * c + 8);
    EXPECT_EQ(parts.size(), 1u) << "cube " << c << " is split";
  }
  const int p0 = partOf[0], p1 = partOf[8], p2 = partOf[16];
  EXPECT_EQ(parent[p0], -1) << "the cube that never moves is the root";
  EXPECT_EQ(parent[p1], p0);
  EXPECT_EQ(parent[p2], p1);
}

TEST(PoseModel, FeaturesAreJointRotationsWhateverTheCharacterStands) {
  const Mesh mesh = cubeChain();
  PoseModel model = chainModel();
  const PosePredictor predictor(model, mesh);
  ASSERT_EQ(model.poseFeatureCount(), 3 + 9 + 9);
  const double a1 = 0.7, a2 = -0.4;
  const Eigen::Matrix3d world =
      Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  for (const Eigen::Matrix3d& q :
       std::vector<Eigen::Matrix3d>{Eigen::Matrix3d::Identity(), world}) {
    const std::vector<float> frame = chainFrames(mesh, {a1}, {a2}, q);
    std::vector<double> x(21);
    predictor.poseFeatures(frame.data(), x.data());
    // The root's feature: the up axis seen from the root part, minus up.
    const Eigen::Vector3d up(0, 0, 1);
    const Eigen::Vector3d g = q.transpose() * up - up;
    const Eigen::Matrix3d r1 =
        Eigen::AngleAxisd(a1, Eigen::Vector3d::UnitZ()).matrix() - Eigen::Matrix3d::Identity();
    const Eigen::Matrix3d r2 =
        Eigen::AngleAxisd(a2, Eigen::Vector3d::UnitY()).matrix() - Eigen::Matrix3d::Identity();
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(x[c], g[c], testing::kAlignTol);
    }
    for (int i = 0; i < 9; ++i) {
      EXPECT_NEAR(x[3 + i], r1(i / 3, i % 3), testing::kAlignTol) << "joint 1 entry " << i;
      EXPECT_NEAR(x[12 + i], r2(i / 3, i % 3), testing::kAlignTol) << "joint 2 entry " << i;
    }
  }
}

TEST(PoseModel, SiblingFeaturesAreTheRotationOfOnePartSeenFromItsSibling) {
  // The chain's cubes 1 and 2 declared children of cube 0 (siblings): the extra block is the
  // weight times (R1^T R2 - I), the rotation of cube 2 seen from cube 1 (here the hinge's a2,
  // whatever the world rotation); off (weight 0) and on a chain there is no such block.
  const Mesh mesh = cubeChain();
  PoseModel model = chainModel();
  model.siblingWeight = 0.5;
  EXPECT_TRUE(model.siblingPairs().empty());
  EXPECT_EQ(model.poseFeatureCount(), 3 + 9 + 9);
  model.parent = {-1, 0, 0};
  ASSERT_EQ(model.siblingPairs(), (std::vector<std::array<int, 2>>{{1, 2}}));
  ASSERT_EQ(model.poseFeatureCount(), 3 + 9 + 9 + 9);
  const PosePredictor predictor(model, mesh);
  const double a1 = 0.7, a2 = -0.4;
  const Eigen::Matrix3d world =
      Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  const Eigen::Matrix3d sibling = 0.5 * (Eigen::AngleAxisd(a2, Eigen::Vector3d::UnitY()).matrix() -
                                         Eigen::Matrix3d::Identity());
  for (const Eigen::Matrix3d& q :
       std::vector<Eigen::Matrix3d>{Eigen::Matrix3d::Identity(), world}) {
    const std::vector<float> frame = chainFrames(mesh, {a1}, {a2}, q);
    std::vector<double> x(30);
    predictor.poseFeatures(frame.data(), x.data());
    for (int i = 0; i < 9; ++i) {
      EXPECT_NEAR(x[21 + i], sibling(i / 3, i % 3), testing::kAlignTol) << "entry " << i;
    }
  }
  model.siblingWeight = 0.0;
  EXPECT_EQ(model.poseFeatureCount(), 3 + 9 + 9);
}

TEST_F(PoseModelClTest, TheModelBeatsTheBindingOnFramesItNeverSaw) {
  const Database& db = sampleDatabase();
  ASSERT_FALSE(db.poseModel.empty()) << "db build fits the pose model by default";
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const auto truth = openPointCache(sample("test.driven.pc2"));
  const std::vector<int> frames = driver->frames();
  const std::vector<float> pose = readFrames(*driver, frames);
  const std::vector<float> expected = readFrames(*truth, frames);
  testing::Backends cl = clBackends();
  EvaluatorSettings model;
  model.resolve = false;
  EvaluatorSettings bind = model;
  bind.weightMode = WeightMode::kBind;
  const Evaluation withModel = Evaluator(db, model, cl.view()).evaluate(frames, pose);
  const Evaluation binding = Evaluator(db, bind, cl.view()).evaluate(frames, pose);
  const double modelError = testing::meanVertexDistance(withModel.cloth, expected);
  const double bindError = testing::meanVertexDistance(binding.cloth, expected);
  // The simulated truth of the sleeve's test clip (a motion the train clip does not hold).
  EXPECT_LT(modelError, 0.8 * bindError)
      << "pose model " << modelError << " vs binding " << bindError << " (scene units)";
  for (const FrameRecord& record : withModel.records) {
    EXPECT_GE(record.predictedError, 0.0);
    EXPECT_GE(record.poseDistance, 0.0);
    EXPECT_TRUE(record.flagged == 0 || record.flagged == 1);
  }
}

TEST_F(PoseModelClTest, ANegativeErrorLineStillPredictsEveryFrame) {
  // A database written before the line was kept non-negative may hold a negative bias: its
  // predictions are clamped at 0, never dropped (the report writes a prediction >= 0 only).
  Database db = sampleDatabase();
  db.poseModel.errorBias = -1.0e6;
  db.poseModel.verdictLevel = 0.0;  // such a database has no calibrated verdict either
  db.poseModel.verdictMargin = 0.0;
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const std::vector<int> frames = driver->frames();
  testing::Backends cl = clBackends();
  const Evaluation out =
      Evaluator(db, EvaluatorSettings(), cl.view()).evaluate(frames, readFrames(*driver, frames));
  for (const FrameRecord& record : out.records) {
    EXPECT_EQ(record.predictedError, 0.0) << "frame " << record.frame;
    EXPECT_EQ(record.flagged, 0) << "frame " << record.frame;
  }
}

TEST(PoseModel, TheErrorLineIsTheBestNonNegativeLine) {
  // Against a brute-force search over a grid of non-negative lines: the fitted line's squared
  // error is never above the grid's best, and the line is within one grid step of it.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int n = 200;
  Eigen::VectorXd sigma(n);
  for (int i = 0; i < n; ++i) {
    sigma[i] = 0.3 + 0.7 * unit(rng);
  }
  struct Case {
    const char* what;
    double bias, scale;  // the truth, before noise
  };
  // Inside the feasible set, and two whose unconstrained fits have a negative bias or scale.
  for (const Case c : {Case{"interior", 0.01, 0.02}, Case{"negative bias", -0.5, 2.0},
                       Case{"negative scale", 1.5, -1.0}}) {
    Eigen::VectorXd error(n);
    for (int i = 0; i < n; ++i) {
      error[i] = std::max(0.0, c.bias + c.scale * sigma[i] + 0.005 * (unit(rng) - 0.5));
    }
    const std::array<double, 2> line = fitErrorLine(sigma, error);
    ASSERT_GE(line[0], 0.0) << c.what;
    ASSERT_GE(line[1], 0.0) << c.what;
    const auto cost = [&](double b, double s) {
      return (error.array() - b - s * sigma.array()).square().sum();
    };
    const double step = 1e-3;
    double best = cost(0.0, 0.0), bestBias = 0.0, bestScale = 0.0;
    for (int i = 0; i <= 2000; ++i) {
      for (int j = 0; j <= 2500; ++j) {
        const double value = cost(i * step, j * step);
        if (value < best) {
          best = value, bestBias = i * step, bestScale = j * step;
        }
      }
    }
    EXPECT_LE(cost(line[0], line[1]), best * (1.0 + 1e-12)) << c.what;
    EXPECT_NEAR(line[0], bestBias, step) << c.what;
    EXPECT_NEAR(line[1], bestScale, step) << c.what;
  }
  EXPECT_THROW(fitErrorLine(sigma, Eigen::VectorXd::Zero(3)), Error);
}

TEST(PoseModel, TheVerdictMarginIsTheConformalRankOfTheResiduals) {
  // Against counting: the margin is a residual error - predicted of the calibration frames (or
  // 0), at least ceil((n + 1) level) of the n residuals are within it and, when it is above 0,
  // fewer are strictly below it.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int n : {1, 9, 10, 57, 400}) {
    for (double level : {0.5, 0.8, 0.9, 0.95}) {
      std::vector<double> error(n), predicted(n), residual(n);
      for (int i = 0; i < n; ++i) {
        predicted[i] = 0.01 + 0.02 * unit(rng);
        error[i] = std::max(0.0, predicted[i] + 0.01 * (unit(rng) - 0.3));
        residual[i] = error[i] - predicted[i];
      }
      const double margin = conformalMargin(error, predicted, level);
      const long need = std::min<long>(n, static_cast<long>(std::ceil((n + 1) * level)));
      const long within =
          std::count_if(residual.begin(), residual.end(), [&](double r) { return r <= margin; });
      const long below =
          std::count_if(residual.begin(), residual.end(), [&](double r) { return r < margin; });
      EXPECT_GE(within, need) << "n " << n << " level " << level;
      EXPECT_GE(margin, 0.0);
      if (margin > 0.0) {
        EXPECT_LT(below, need) << "n " << n << " level " << level << ": not the smallest";
        EXPECT_TRUE(std::find(residual.begin(), residual.end(), margin) != residual.end());
      }
    }
  }
  // Predictions above every error: no margin.
  EXPECT_EQ(conformalMargin({0.01, 0.02}, {0.03, 0.04}, 0.9), 0.0);
  EXPECT_THROW(conformalMargin({0.01}, {0.01, 0.02}, 0.9), Error);
  EXPECT_THROW(conformalMargin({}, {}, 0.9), Error);
  EXPECT_THROW(conformalMargin({0.01}, {0.01}, 1.0), Error);
}

TEST_F(PoseModelClTest, AFrameIsFlaggedByItsBoundNotItsPrediction) {
  // With the verdict's margin m, a frame whose predicted error p is under the tolerance but
  // p + m is over it is flagged; the bound is p + m on every frame; a model from before the
  // verdict was calibrated (level 0, margin 0) flags by its prediction.
  const Database& db = sampleDatabase();
  ASSERT_GT(db.poseModel.verdictLevel, 0.0) << "db build calibrates the verdict";
  ASSERT_GE(db.poseModel.verdictMargin, 0.0);
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const std::vector<int> frames = driver->frames();
  const std::vector<float> pose = readFrames(*driver, frames);
  testing::Backends cl = clBackends();
  Database scaled = db;
  scaled.poseModel.verdictMargin = 0.004;
  Database old = db;
  old.poseModel.verdictLevel = 0.0;
  old.poseModel.verdictMargin = 0.0;
  // A tolerance between the frames' predictions, so some frames fall on each side.
  const Evaluation probe = Evaluator(old, EvaluatorSettings(), cl.view()).evaluate(frames, pose);
  std::vector<double> predicted;
  for (const FrameRecord& record : probe.records) {
    predicted.push_back(record.predictedError);
  }
  std::sort(predicted.begin(), predicted.end());
  EvaluatorSettings settings;
  settings.coverageTolerance = predicted[predicted.size() * 3 / 4];
  const Evaluation a = Evaluator(scaled, settings, cl.view()).evaluate(frames, pose);
  const Evaluation b = Evaluator(old, settings, cl.view()).evaluate(frames, pose);
  int flaggedOnlyByBound = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const FrameRecord& x = a.records[i];
    EXPECT_DOUBLE_EQ(x.errorBound, x.predictedError + 0.004) << "frame " << x.frame;
    EXPECT_EQ(x.flagged, x.errorBound > settings.coverageTolerance ? 1 : 0) << "frame " << x.frame;
    EXPECT_EQ(b.records[i].errorBound, b.records[i].predictedError) << "frame " << x.frame;
    EXPECT_EQ(b.records[i].flagged, b.records[i].predictedError > settings.coverageTolerance);
    flaggedOnlyByBound += x.flagged == 1 && b.records[i].flagged == 0;
  }
  EXPECT_GT(flaggedOnlyByBound, 0) << "the tolerance was chosen so the bound flags more frames";
}

TEST_F(PoseModelClTest, BelowTheSmallestBoundEveryFrameIsFlaggedAndTheEvaluatorSaysSo) {
  // The smallest bound a frame can get is the error line at sigma 0 plus the margin: a coverage
  // tolerance under it flags every frame, and the evaluator (so every tool's bake) warns once.
  const Database& db = sampleDatabase();
  const PoseModel& m = db.poseModel;
  const double smallest = std::max(0.0, m.errorBias) + m.verdictMargin;
  EXPECT_DOUBLE_EQ(m.smallestErrorBound(), smallest);
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const std::vector<int> frames = driver->frames();
  const std::vector<float> pose = readFrames(*driver, frames);
  testing::Backends cl = clBackends();
  const auto warned = [](const Evaluator& e) {
    return std::count_if(e.warnings().begin(), e.warnings().end(), [](const std::string& w) {
      return w.find("every frame will be flagged for simulation") != std::string::npos;
    });
  };
  EvaluatorSettings below;
  below.coverageTolerance = 0.999 * smallest;
  Evaluator under(db, below, cl.view());
  EXPECT_EQ(warned(under), 1);
  for (const FrameRecord& record : under.evaluate(frames, pose).records) {
    EXPECT_EQ(record.flagged, 1) << "frame " << record.frame;
  }
  EvaluatorSettings above;
  above.coverageTolerance = 1.001 * smallest;
  EXPECT_EQ(warned(Evaluator(db, above, cl.view())), 0);
  // The default tolerance, 2% of the rest cloth's diagonal, warns exactly when it is under.
  const Mesh& cloth = db.drivenMesh;
  const double diagonal =
      (cloth.positions.colwise().maxCoeff() - cloth.positions.colwise().minCoeff())
          .cast<double>()
          .norm();
  EXPECT_EQ(warned(Evaluator(db, EvaluatorSettings(), cl.view())), 0.02 * diagonal < smallest);
  // Without the pose model's weights nothing is flagged, so nothing is said.
  EvaluatorSettings qp = below;
  qp.weightMode = WeightMode::kQp;
  EXPECT_EQ(warned(Evaluator(db, qp, cl.view())), 0);
}

TEST(PoseModel, TheHeldOutOutlookCountsTheCalibrationFramesWithinTheTolerance) {
  // heldOutEnoughShare counts the frames the verdict was calibrated on (the cross-validation
  // with one clip, each clip left out with several) whose bound is within the tolerance.
  PoseModel m;
  m.errorBias = 0.002;
  m.errorScale = 0.01;
  m.verdictMargin = 0.003;
  m.frameSigmas = {0.0, 0.1, 0.2, 0.5, 1.0};  // bounds 0.005, 0.006, 0.007, 0.010, 0.015
  m.frameErrors.assign(5, 0.0);
  EXPECT_DOUBLE_EQ(heldOutEnoughShare(m, 0.0049), 0.0);
  EXPECT_DOUBLE_EQ(heldOutEnoughShare(m, 0.0070001), 3.0 / 5.0);
  EXPECT_DOUBLE_EQ(heldOutEnoughShare(m, 0.02), 1.0);
  m.leftOutErrors.assign(4, 0.0);
  m.leftOutSigmas = {1.0, 1.0, 1.0, 0.0};
  EXPECT_DOUBLE_EQ(heldOutEnoughShare(m, 0.0070001), 1.0 / 4.0) << "several clips: left out";
  EXPECT_DOUBLE_EQ(heldOutEnoughShare(PoseModel(), 1.0), 0.0) << "no held-out figures";
}

TEST(PoseModel, EachClipsContributionIsMeasuredByLeavingItOut) {
  // The sample's train clip given twice: left out, a clip is predicted by its identical twin
  // far better than the clip alone cross-validates (its held-out blocks' poses are new to it);
  // a clip of other poses (the test clip) is predicted by the train clip worse than it is
  // cross-validated once it is in.
  const testing::SampleClips s;
  DatabaseBuildOptions options;
  options.count = 10;
  const Database twins = buildDatabase(s.driver, s.driven, *s.trainDriver, *s.trainDriven,
                                       {{s.trainDriver.get(), s.trainDriven.get(), {}}}, options);
  const std::vector<ClipContribution>& t = twins.poseModel.clipErrors;
  ASSERT_EQ(t.size(), 2u);
  for (int c = 0; c < 2; ++c) {
    EXPECT_EQ(t[c].frames, static_cast<int>(s.trainDriver->frames().size()));
    EXPECT_LT(t[c].without[c], 0.1 * sampleDatabase().poseModel.crossValidationError)
        << "clip " << c + 1 << " predicted by its twin";
  }
  const Database other = buildDatabase(s.driver, s.driven, *s.trainDriver, *s.trainDriven,
                                       {{s.testDriver.get(), s.testDriven.get(), {}}}, options);
  const std::vector<ClipContribution>& o = other.poseModel.clipErrors;
  ASSERT_EQ(o.size(), 2u);
  EXPECT_GT(o[1].without[1], o[1].withAll[1]) << "the test clip's poses are new to the train clip";
  // withAll is the mean of the model's own cross-validated frame errors over each clip.
  const std::vector<double>& e = other.poseModel.frameErrors;
  const int first = o[0].frames;
  EXPECT_DOUBLE_EQ(o[0].withAll[0], std::accumulate(e.begin(), e.begin() + first, 0.0) / first);
  EXPECT_NEAR(o[0].withAll[1], std::accumulate(e.begin() + first, e.end(), 0.0) / o[1].frames,
              1e-12);
  // Each frame's left-out error averages to its clip's "without" entry, and with several clips
  // the verdict is calibrated on those left-out errors.
  const PoseModel& m = other.poseModel;
  ASSERT_EQ(m.leftOutErrors.size(), e.size());
  EXPECT_NEAR(
      std::accumulate(m.leftOutErrors.begin(), m.leftOutErrors.begin() + first, 0.0) / first,
      o[0].without[0], 1e-12);
  EXPECT_NEAR(
      std::accumulate(m.leftOutErrors.begin() + first, m.leftOutErrors.end(), 0.0) / o[1].frames,
      o[1].without[1], 1e-12);
  std::vector<double> predicted;
  for (double sigma : m.leftOutSigmas) {
    predicted.push_back(m.predictedError(sigma));
  }
  EXPECT_EQ(m.verdictMargin, conformalMargin(m.leftOutErrors, predicted, m.verdictLevel));
}

TEST_F(PoseModelClTest, HistoryReadsTheSameFramesInBlocksAsInOneCall) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const std::vector<int> frames = driver->frames();
  const std::vector<float> pose = readFrames(*driver, frames);
  testing::Backends cl = clBackends();
  const EvaluatorSettings settings;  // the defaults: the pose model
  Evaluator whole(db, settings, cl.view());
  ASSERT_GT(whole.historyFrames(), 0);
  const Evaluation all = whole.evaluate(frames, pose);
  const std::size_t dv = static_cast<std::size_t>(db.driverVertexCount()) * 3;
  const std::size_t dd = static_cast<std::size_t>(db.drivenVertexCount()) * 3;
  // Blocks of 7 with the history as warm-up frames (what the bake reads from the cache), each
  // on a fresh evaluator: no memory of earlier calls.
  for (std::size_t begin = 0; begin < frames.size(); begin += 7) {
    const std::size_t end = std::min(frames.size(), begin + 7);
    const std::size_t warm = std::min<std::size_t>(begin, whole.historyFrames());
    const std::vector<int> block(frames.begin() + (begin - warm), frames.begin() + end);
    const std::vector<float> blockPose(pose.begin() + (begin - warm) * dv, pose.begin() + end * dv);
    Evaluator fresh(db, settings, cl.view());
    std::vector<float> cloth((end - begin) * dd);
    std::vector<FrameRecord> records(end - begin);
    fresh.evaluate(static_cast<int>(block.size()), block.data(), blockPose.data(), cloth.data(),
                   records.data(), static_cast<int>(warm));
    for (std::size_t i = 0; i < cloth.size(); ++i) {
      ASSERT_EQ(cloth[i], all.cloth[begin * dd + i]) << "block at frame " << frames[begin];
    }
  }
  // One frame per call in order (live playback): the evaluator remembers the history.
  Evaluator live(db, settings, cl.view());
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const Evaluation one = live.evaluate(
        {frames[f]}, std::vector<float>(pose.begin() + f * dv, pose.begin() + (f + 1) * dv));
    for (std::size_t i = 0; i < dd; ++i) {
      ASSERT_EQ(one.cloth[i], all.cloth[f * dd + i]) << "live frame " << frames[f];
    }
  }
}

TEST(PoseModel, TheDatabaseKeepsTheModel) {
  const Database& db = sampleDatabase();
  TempDir dir;
  saveDatabase(dir.file("db.dsdb"), db);
  const Database back = loadDatabase(dir.file("db.dsdb"));
  const PoseModel& a = db.poseModel;
  const PoseModel& b = back.poseModel;
  EXPECT_EQ(a.partOf, b.partOf);
  EXPECT_EQ(a.parent, b.parent);
  EXPECT_EQ(a.frames, b.frames);
  EXPECT_EQ(a.features, b.features);
  EXPECT_EQ(a.coefficients, b.coefficients);
  EXPECT_EQ(a.basis, b.basis);
  EXPECT_EQ(a.lengthScale, b.lengthScale);
  EXPECT_EQ(a.ridge, b.ridge);
  EXPECT_EQ(a.errorScale, b.errorScale);
  EXPECT_EQ(a.verdictLevel, b.verdictLevel);
  EXPECT_EQ(a.verdictMargin, b.verdictMargin);
  EXPECT_EQ(db.contentHash(), back.contentHash());
  Database recalibrated = db;
  recalibrated.poseModel.verdictMargin += 0.001;
  EXPECT_NE(recalibrated.contentHash(), db.contentHash()) << "the verdict is part of the content";
  Database without = db;
  without.poseModel = PoseModel();
  EXPECT_NE(without.contentHash(), db.contentHash()) << "the model is part of the content";
  // Sibling features (the sample's chain declared a root with two children): the weight comes
  // back and is part of the content; a weight on parts without a common parent is refused.
  Database siblings = db;
  PoseModel& m = siblings.poseModel;
  m.parent = {-1, 0, 0};
  m.siblingWeight = 0.5;
  m.features.assign(static_cast<std::size_t>(m.frameCount() * m.featureCount()), 0.25f);
  saveDatabase(dir.file("siblings.dsdb"), siblings);
  const Database siblingsBack = loadDatabase(dir.file("siblings.dsdb"));
  EXPECT_EQ(siblingsBack.poseModel.siblingWeight, 0.5);
  EXPECT_EQ(siblingsBack.poseModel.features, m.features);
  EXPECT_EQ(siblingsBack.contentHash(), siblings.contentHash());
  Database heavier = siblings;
  heavier.poseModel.siblingWeight = 0.25;
  EXPECT_NE(heavier.contentHash(), siblings.contentHash()) << "the weight is part of the content";
  // The bake report's settings name the weight (docs/schemas/bake_report.schema.json), and
  // only when the model has the sibling features.
  testing::Backends host = testing::hostBackends();
  const auto poseModelSettings = [&](const Database& d) {
    return nlohmann::json::parse(
        Evaluator(d, EvaluatorSettings(), host.view()).describeSettings())["pose_model"];
  };
  EXPECT_EQ(poseModelSettings(siblingsBack)["sibling_weight"], 0.5);
  EXPECT_FALSE(poseModelSettings(db).contains("sibling_weight"));
  Database chain = db;
  chain.poseModel.siblingWeight = 0.5;  // the sample's parts are a chain: no pair
  saveDatabase(dir.file("chain.dsdb"), chain);
  try {
    loadDatabase(dir.file("chain.dsdb"));
    ADD_FAILURE() << "a sibling weight without sibling parts was read";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("sibling_weight"), std::string::npos) << error.what();
  }
}

TEST(PoseModel, RigFilesGiveThePartsOfTheirHeaviestBones) {
  std::vector<int> partOf, parentOf;
  parseRigParts(R"({"bone_names": ["root", "arm", "hand", "unused"],
                    "bones": [{"name": "root", "parent": null}, {"name": "arm", "parent": "root"},
                              {"name": "unused", "parent": "arm"},
                              {"name": "hand", "parent": "unused"}],
                    "driver_weights": [[1, 0, 0, 0], [0.2, 0.8, 0, 0], [0, 0.4, 0.6, 0]]})",
                "rig.json", 3, partOf, parentOf);
  EXPECT_EQ(partOf, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(parentOf, (std::vector<int>{-1, 0, 1})) << "hand hangs off arm past the unused bone";
  const auto refuses = [](const std::string& text, int vertices) {
    std::vector<int> p, q;
    try {
      parseRigParts(text, "rig.json", vertices, p, q);
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kInput);
      EXPECT_NE(std::string(error.what()).find("rig.json"), std::string::npos);
      return true;
    }
    return false;
  };
  EXPECT_TRUE(refuses(R"({"bone_names": ["a"], "driver_weights": [[1]]})", 2));
  EXPECT_TRUE(refuses(R"({"bone_names": ["a", "a"], "driver_weights": [[1, 0]]})", 1));
  EXPECT_TRUE(refuses(R"({"bone_names": ["a"], "driver_weights": [["x"]]})", 1));
  EXPECT_TRUE(refuses(R"([1, 2])", 1));
}

}  // namespace
}  // namespace drivenshape
