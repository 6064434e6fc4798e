// SPDX-License-Identifier: Apache-2.0
// The fidelity stages of the bake (issue 4) on the bundled sample shot (a slice of the sleeve
// scene): rigid alignment, world-space invariance, penetration resolution, local-frame
// blending, region-local weights and the temporal bound, each against an independent
// reference (a known motion, the transformed bake, the host backend, the transfer of one
// shape, a brute-force ring distance, the QP's own box).

#include <drivenshape/bake.h>

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <numeric>
#include <queue>
#include <random>

#include <drivenshape/database.h>
#include <drivenshape/error.h>
#include <drivenshape/regions.h>

#include "align.h"
#include "closest.h"

#include "bake_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using testing::Backends;
using testing::buildSample;
using testing::hostBackends;
using testing::readBake;
using testing::sample;
using testing::sampleDatabase;
using testing::TempDir;
using FidelityTest = testing::BakeClTest;

/// Worst per-vertex distance between two frame blocks, as a fraction of each frame's bounding-
/// box diagonal (of `a`).
double worstRelativeDistance(const std::vector<float>& a, const std::vector<float>& b,
                             int frameCount, int vertexCount, int* worstFrame = nullptr) {
  const std::size_t values = static_cast<std::size_t>(vertexCount) * 3;
  double worst = 0;
  for (int f = 0; f < frameCount; ++f) {
    const double diagonal = computeBounds(&a[f * values], vertexCount).diagonal();
    for (int v = 0; v < vertexCount; ++v) {
      const Eigen::Vector3d p(a[f * values + 3 * v], a[f * values + 3 * v + 1],
                              a[f * values + 3 * v + 2]);
      const Eigen::Vector3d q(b[f * values + 3 * v], b[f * values + 3 * v + 1],
                              b[f * values + 3 * v + 2]);
      const double d = (p - q).norm() / diagonal;
      if (d > worst) {
        worst = d;
        if (worstFrame != nullptr) {
          *worstFrame = f;
        }
      }
    }
  }
  return worst;
}

/// A motion that travels and turns over the clip: frame i of n is rotated by up to 100 degrees
/// about a tilted vertical axis and carried 4 m along a curve.
RigidTransform travellingMotion(int i, int n) {
  const double s = double(i) / std::max(1, n - 1);
  RigidTransform motion;
  motion.rotation =
      Eigen::AngleAxisd(1.75 * s, Eigen::Vector3d(0.1, -0.2, 1.0).normalized()).toRotationMatrix();
  motion.translation = Eigen::Vector3d(4.0 * s, 1.5 * std::sin(3.0 * s), 0.2 * s);
  return motion;
}

// ---- Rigid alignment ----

TEST(RigidAlign, RecoversAKnownMotionOnAGroupWhileOtherVerticesMove) {
  const Mesh mesh = readObj(sample("driver_rest.obj"));
  const int v = mesh.vertexCount();
  std::mt19937 random(testing::testSeed());
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const Eigen::Matrix3d rotation =
      Eigen::AngleAxisd(
          2.5, Eigen::Vector3d(uniform(random), uniform(random), uniform(random)).normalized())
          .toRotationMatrix();
  const Eigen::Vector3d translation(3.0, -7.0, 1.5);
  // The selection: the first half of the vertices; the others get noise that must not matter.
  const std::string group = "0-" + std::to_string(v / 2);
  const std::vector<int> selected = selectVertices(mesh, group, "test");
  ASSERT_EQ(static_cast<int>(selected.size()), v / 2 + 1);
  std::vector<float> frame(static_cast<std::size_t>(v) * 3);
  for (int i = 0; i < v; ++i) {
    Eigen::Vector3d p = mesh.positions.row(i).cast<double>().transpose();
    if (i > v / 2) {
      p += 0.3 * Eigen::Vector3d(uniform(random), uniform(random), uniform(random));
    }
    const Eigen::Vector3d q = rotation * p + translation;
    for (int a = 0; a < 3; ++a) {
      frame[3 * i + a] = static_cast<float>(q(a));
    }
  }
  const RigidAligner aligner(mesh, mesh.positions.data(), selected, "test");
  const RigidTransform fit = aligner.fit(frame.data());
  // The fit maps the frame back onto the rest: the inverse of the known motion.
  const double diagonal = computeBounds(mesh.positions.data(), v).diagonal();
  const double rotationError = (fit.rotation - rotation.transpose()).cwiseAbs().maxCoeff();
  const double translationError =
      (fit.translation + rotation.transpose() * translation).norm() / diagonal;
  std::printf(
      "[ measured ] alignment: rotation error %.3g, translation error %.3g of the "
      "diagonal (limit %.0e)\n",
      rotationError, translationError, testing::kAlignTol);
  EXPECT_LE(rotationError, testing::kAlignTol);
  EXPECT_LE(translationError, testing::kAlignTol);
  EXPECT_NEAR(fit.rotation.determinant(), 1.0, testing::kAlignTol);
  // A mirrored frame still gives a proper rotation (no reflection).
  std::vector<float> mirrored = frame;
  for (int i = 0; i < v; ++i) {
    mirrored[3 * i] = -mirrored[3 * i];
  }
  EXPECT_NEAR(aligner.fit(mirrored.data()).rotation.determinant(), 1.0, testing::kAlignTol);
}

TEST(RigidAlign, BadSelectionsAreInputErrorsNamingTheProblem) {
  const Mesh mesh = readObj(sample("driver_rest.obj"));
  auto expectInputError = [&](const std::function<void()>& call, const std::string& fragment) {
    try {
      call();
      ADD_FAILURE() << "no error; expected one mentioning '" << fragment << "'";
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kInput) << error.what();
      EXPECT_NE(std::string(error.what()).find(fragment), std::string::npos) << error.what();
    }
  };
  expectInputError([&] { selectVertices(mesh, "left_leg", "--align-group"); },
                   "no group 'left_leg' (its groups: arm)");
  expectInputError([&] { selectVertices(mesh, "0-99999999", "--align-group"); }, "outside 0-");
  expectInputError(
      [&] {
        RigidAligner(mesh, mesh.positions.data(), {0, 1}, "--align-group '0,1'");
      },
      "at least 3 non-collinear");
  // Three collinear vertices on a hand-made mesh.
  Mesh line;
  line.positions.resize(4, 3);
  line.positions << 0, 0, 0, 1, 1, 1, 2, 2, 2, 0, 1, 0;
  line.faceStart = {0, 3};
  line.faceVertices = {0, 1, 3};
  line.faceGroup = {0};
  line.groupNames = {"default"};
  line.triangulate();
  expectInputError(
      [&] {
        RigidAligner(line, line.positions.data(), {0, 1, 2}, "--align-group");
      },
      "collinear");
  EXPECT_NO_THROW(RigidAligner(line, line.positions.data(), {0, 1, 3}, "--align-group"));
  // The whole mesh by name works ("o arm").
  EXPECT_EQ(static_cast<int>(selectVertices(mesh, "arm", "--align-group").size()),
            mesh.vertexCount());
}

// The acceptance test of issue 4: the shot's driver carried along a travelling, turning path
// gives the same bake carried along the same path, with default settings.
/// The sample driver as an articulated body: the half of the arm below the middle of its
/// longest rest axis is the rigid part, the other half bends by `bend` radians about a joint
/// axis through the middle, then the whole is carried by `motion`.
std::vector<float> articulatedFrame(const Mesh& mesh, const std::vector<bool>& rigidPart,
                                    const Eigen::Vector3d& joint, double bend,
                                    const RigidTransform& motion) {
  const Eigen::Matrix3d bent =
      Eigen::AngleAxisd(bend, Eigen::Vector3d(0.3, 0.2, 1.0).normalized()).toRotationMatrix();
  std::vector<float> frame(static_cast<std::size_t>(mesh.vertexCount()) * 3);
  for (int v = 0; v < mesh.vertexCount(); ++v) {
    Eigen::Vector3d p = mesh.positions.row(v).cast<double>().transpose();
    if (!rigidPart[v]) {
      p = joint + bent * (p - joint);
    }
    const Eigen::Vector3d q = motion.rotation * p + motion.translation;
    for (int a = 0; a < 3; ++a) {
      frame[3 * v + a] = static_cast<float>(q(a));
    }
  }
  return frame;
}

TEST(RigidAlign, RigidityWeightsLockOntoTheRigidPartWhileTheOtherArticulates) {
  constexpr double kDegree = 3.14159265358979323846 / 180.0;
  const Mesh mesh = readObj(sample("driver_rest.obj"));
  const int v = mesh.vertexCount();
  const Bounds bounds = computeBounds(mesh.positions.data(), v);
  int axis = 0;
  (bounds.max - bounds.min).maxCoeff(&axis);
  const Eigen::Vector3d joint = (0.5f * (bounds.min + bounds.max)).cast<double>();
  std::vector<bool> rigidPart(static_cast<std::size_t>(v));
  int rigidCount = 0;
  for (int i = 0; i < v; ++i) {
    rigidPart[i] = mesh.positions(i, axis) < joint(axis);
    rigidCount += rigidPart[i] ? 1 : 0;
  }
  ASSERT_GT(rigidCount, v / 4);
  ASSERT_LT(rigidCount, 3 * v / 4);
  // Examples: the joint bends from 10 to 100 degrees while the whole body travels and turns.
  const int exampleCount = 12;
  std::vector<float> examples;
  for (int e = 0; e < exampleCount; ++e) {
    const std::vector<float> frame =
        articulatedFrame(mesh, rigidPart, joint, (10.0 + 90.0 * e / (exampleCount - 1)) * kDegree,
                         travellingMotion(e, exampleCount));
    examples.insert(examples.end(), frame.begin(), frame.end());
  }
  const std::vector<int> all = selectVertices(mesh, "", "test");
  RigidAligner weighted(mesh, mesh.positions.data(), all, "test");
  const RigidAligner areaOnly(mesh, mesh.positions.data(), all, "test");
  RigidityOptions threeThreads;
  threeThreads.threads = 3;
  weighted.weightByRigidity(examples.data(), exampleCount, threeThreads);
  // A shot frame that is none of the examples: another bend, another motion.
  const RigidTransform motion = travellingMotion(5, 7);
  const std::vector<float> shot = articulatedFrame(mesh, rigidPart, joint, 1.2, motion);
  // The alignment error: how far the fit leaves the rigid part's shot points from their rest
  // positions (the fit should undo `motion` exactly there), as a fraction of the diagonal.
  const double diagonal = bounds.diagonal();
  auto errors = [&](const RigidTransform& fit) {
    std::vector<float> aligned(shot.size());
    fit.apply(shot.data(), v, aligned.data());
    double worst = 0.0;
    for (int i = 0; i < v; ++i) {
      if (rigidPart[i]) {
        const Eigen::Vector3f d(aligned[3 * i] - mesh.positions(i, 0),
                                aligned[3 * i + 1] - mesh.positions(i, 1),
                                aligned[3 * i + 2] - mesh.positions(i, 2));
        worst = std::max(worst, static_cast<double>(d.norm()) / diagonal);
      }
    }
    return worst;
  };
  const double weightedError = errors(weighted.fit(shot.data()));
  const double areaError = errors(areaOnly.fit(shot.data()));
  double rigidShare = 0.0;
  for (int i = 0; i < v; ++i) {
    rigidShare += rigidPart[weighted.vertices()[i]] ? weighted.weights()[i] : 0.0;
  }
  std::printf(
      "[ measured ] rigidity-weighted fit: error %.3g (limit %.0e), weight on the rigid part "
      "%.6f; area-weighted fit: error %.3g\n",
      weightedError, testing::kRigidityAlignTol, rigidShare, areaError);
  EXPECT_LE(weightedError, testing::kRigidityAlignTol);
  EXPECT_GT(rigidShare, 0.98);
  // The plain area fit is pulled by the bending half: the check above is not vacuous.
  EXPECT_GT(areaError, 10 * testing::kRigidityAlignTol);

  // Deterministic: the same examples give bit-identical weights and fits, on one thread as on
  // several.
  RigidAligner again(mesh, mesh.positions.data(), all, "test");
  RigidityOptions oneThread;
  oneThread.threads = 1;
  again.weightByRigidity(examples.data(), exampleCount, oneThread);
  EXPECT_EQ(again.weights(), weighted.weights());
  EXPECT_EQ(again.fit(shot.data()).rotation, weighted.fit(shot.data()).rotation);
  EXPECT_EQ(again.fit(shot.data()).translation, weighted.fit(shot.data()).translation);

  // Without examples the weights stay the areas; an --align-group selection still restricts
  // the candidates (weights live on the selected vertices only).
  RigidAligner untouched(mesh, mesh.positions.data(), all, "test");
  untouched.weightByRigidity(nullptr, 0);
  EXPECT_EQ(untouched.weights(), areaOnly.weights());
  const std::vector<int> half = selectVertices(mesh, "0-" + std::to_string(v / 2), "test");
  RigidAligner restricted(mesh, mesh.positions.data(), half, "test");
  restricted.weightByRigidity(examples.data(), exampleCount);
  EXPECT_EQ(restricted.weights().size(), half.size());
}

TEST_F(FidelityTest, WorldSpaceShotGivesTheSameBakeUpToTheMotion) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const std::vector<int> frames = driver->frames();
  const int n = static_cast<int>(frames.size());
  const int vp = db.driverVertexCount(), vd = db.drivenVertexCount();
  TempDir dir;
  std::vector<float> moved = readFrames(*driver, frames);
  for (int i = 0; i < n; ++i) {
    travellingMotion(i, n).apply(&moved[i * 3 * vp], vp, &moved[i * 3 * vp]);
  }
  writePc2(dir.file("moved.pc2"), vp, static_cast<float>(frames.front()), n, moved.data());
  const auto movedDriver = openPointCache(dir.file("moved.pc2"));

  const Backends cl = clBackends();
  BakeOptions options;  // defaults: rigid alignment, resolution on
  options.frames = frames;
  options.outputPattern = dir.file("still.####.exr");
  const BakeResult still = bake(db, *driver, cl.view(), options);
  options.outputPattern = dir.file("moved.####.exr");
  const BakeResult travelled = bake(db, *movedDriver, cl.view(), options);

  std::vector<float> expected = readBake(dir.file("still.####.exr"), frames);
  for (int i = 0; i < n; ++i) {
    travellingMotion(i, n).apply(&expected[i * 3 * vd], vd, &expected[i * 3 * vd]);
  }
  const std::vector<float> got = readBake(dir.file("moved.####.exr"), frames);
  int worstFrame = 0;
  const double worst = worstRelativeDistance(expected, got, n, vd, &worstFrame);
  std::printf(
      "[ measured ] world-space invariance: worst %.3g of the diagonal at frame %d "
      "(limit %.0e)\n",
      worst, frames[worstFrame], testing::kWorldInvarianceRelTol);
  EXPECT_LE(worst, testing::kWorldInvarianceRelTol);
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(still.frames[i].insideAfter, travelled.frames[i].insideAfter) << frames[i];
  }

  // Without alignment the talk's method does see the motion: the check above is not vacuous.
  options.evaluator.align = AlignMode::kNone;
  options.outputPattern = dir.file("unaligned.####.exr");
  bake(db, *movedDriver, cl.view(), options);
  const double unaligned =
      worstRelativeDistance(expected, readBake(dir.file("unaligned.####.exr"), frames), n, vd);
  std::printf("[ measured ] the same without alignment: %.3g of the diagonal\n", unaligned);
  EXPECT_GT(unaligned, 100 * testing::kWorldInvarianceRelTol);
}

TEST_F(FidelityTest, BakeRecordsTheAlignmentOfEveryFrame) {
  // Database frame j of the train clip, carried by a known motion, is aligned back by the
  // inverse of that motion composed with the database shape's own alignment.
  const Database& db = sampleDatabase();
  const auto train = openPointCache(sample("train.driver.pc2"));
  const int vp = db.driverVertexCount();
  TempDir dir;
  const RigidTransform motion = travellingMotion(7, 10);
  std::vector<float> frame = readFrames(*train, {db.frames[0]});
  motion.apply(frame.data(), vp, frame.data());
  writePc2(dir.file("one.pc2"), vp, 1.0f, 1, frame.data());
  const auto shot = openPointCache(dir.file("one.pc2"));
  const Backends host = hostBackends();
  BakeOptions options;
  options.frames = {1};
  options.outputPattern = dir.file("one.####.exr");
  const BakeResult result = bake(db, *shot, host.view(), options);
  // The default alignment: weighted by rigidity across the database's driver shapes.
  RigidAligner aligner(db.driverMesh, db.driverMesh.positions.data(),
                       selectVertices(db.driverMesh, "", "test"), "test");
  aligner.weightByRigidity(db.driverShapes.data(), db.shapeCount());
  const RigidTransform ofShape = aligner.fit(&db.driverShapes[0]);
  const Eigen::Matrix3d expected = ofShape.rotation * motion.rotation.transpose();
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> recorded(
      result.frames[0].alignRotation.data());
  EXPECT_LE((recorded - expected).cwiseAbs().maxCoeff(), testing::kAlignTol);
  // Weight 1 on that shape: the alignment made the moved pose the database pose again.
  EXPECT_NEAR(result.frames[0].weights[0], 1.0, 1e-3);
}

// ---- OpenCL vs host for every new stage ----

TEST_F(FidelityTest, OpenClMatchesHostWithAlignmentLocalBlendRegionsAndResolution) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  TempDir dir;
  // Two regions split along the sleeve's length (upper arm / forearm by rest z).
  const Mesh& driverMesh = db.driverMesh;
  const Mesh& drivenMesh = db.drivenMesh;
  auto half = [](const Mesh& mesh, bool upper) {
    const double middle =
        0.5 * (mesh.positions.col(2).minCoeff() + mesh.positions.col(2).maxCoeff());
    nlohmann::json list = nlohmann::json::array();
    for (int v = 0; v < mesh.vertexCount(); ++v) {
      if ((mesh.positions(v, 2) >= middle) == upper) {
        list.push_back(v);
      }
    }
    return nlohmann::json{{"vertices", list}};
  };
  const nlohmann::json regions{
      {"falloff", 3},
      {"regions",
       {{{"name", "upper"}, {"driver", half(driverMesh, true)}, {"driven", half(drivenMesh, true)}},
        {{"name", "lower"},
         {"driver", half(driverMesh, false)},
         {"driven", half(drivenMesh, false)}}}}};
  std::ofstream(dir.file("regions.json")) << regions.dump();

  BakeOptions options;
  options.frames = driver->frames();
  options.batchFrames = 16;
  options.evaluator.blend = BlendMode::kLocal;
  // These stages alone: the strain limit's own host comparison is test_evaluator's, within its
  // tolerance (kStrainLimitDeviceVsHostRelTol), and the resolution's counts below follow it.
  options.evaluator.strainLimit = 0.0;
  options.regionsPath = dir.file("regions.json");
  const Backends host = hostBackends();
  const Backends cl = clBackends();
  options.outputPattern = dir.file("host.####.exr");
  const BakeResult hostResult = bake(db, *driver, host.view(), options);
  options.outputPattern = dir.file("cl.####.exr");
  const BakeResult clResult = bake(db, *driver, cl.view(), options);
  const int n = static_cast<int>(options.frames.size());
  const double worst = worstRelativeDistance(readBake(dir.file("host.####.exr"), options.frames),
                                             readBake(dir.file("cl.####.exr"), options.frames), n,
                                             db.drivenVertexCount());
  std::printf(
      "[ measured ] align + local blend + regions + resolution: worst OpenCL-vs-host "
      "%.3g of the diagonal (limit %.0e)\n",
      worst, testing::kDeviceVsHostRelTol);
  EXPECT_LE(worst, testing::kDeviceVsHostRelTol);
  int resolved = 0;
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(clResult.frames[i].resolved, hostResult.frames[i].resolved) << i;
    EXPECT_EQ(clResult.frames[i].insideAfter, hostResult.frames[i].insideAfter) << i;
    resolved += clResult.frames[i].resolved;
  }
  EXPECT_GT(resolved, 0) << "the resolution never ran: the comparison is vacuous";

  // World blending with the correction: same blended inputs for both correction backends
  // (ties on the blended pose may otherwise bind differently), resolution on both.
  options.evaluator.blend = BlendMode::kWorld;
  options.regionsPath.clear();
  options.outputPattern = dir.file("host-world.####.exr");
  testing::MixedDevice mixed(cl.view(), host.view());
  bake(db, *driver, mixed, options);
  options.outputPattern = dir.file("cl-world.####.exr");
  bake(db, *driver, cl.view(), options);
  const double worstWorld = worstRelativeDistance(
      readBake(dir.file("host-world.####.exr"), options.frames),
      readBake(dir.file("cl-world.####.exr"), options.frames), n, db.drivenVertexCount());
  std::printf("[ measured ] align + world blend + correction + resolution: worst %.3g\n",
              worstWorld);
  EXPECT_LE(worstWorld, testing::kDeviceVsHostRelTol);
}

// ---- Penetration resolution ----

TEST_F(FidelityTest, ResolutionRemovesPenetrationsWithoutPopping) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  TempDir dir;
  const Backends cl = clBackends();
  BakeOptions options;
  options.frames = driver->frames();
  options.evaluator.align = AlignMode::kNone;  // the talk's bake leaves the most cloth inside
  // The resolution alone: with the strain limit the two bakes' cloth differs before it (the limit
  // keeps the cloth in front of the skin only with the resolution on).
  options.evaluator.strainLimit = 0.0;
  options.outputPattern = dir.file("resolved.####.exr");
  const BakeResult resolved = bake(db, *driver, cl.view(), options);
  options.evaluator.resolve = false;
  options.outputPattern = dir.file("raw.####.exr");
  const BakeResult raw = bake(db, *driver, cl.view(), options);
  long before = 0, after = 0;
  double jumpResolved = 0, jumpRaw = 0;
  for (std::size_t i = 0; i < resolved.frames.size(); ++i) {
    EXPECT_EQ(resolved.frames[i].insideCorrected, raw.frames[i].insideAfter);
    EXPECT_LE(resolved.frames[i].insideAfter, resolved.frames[i].insideCorrected);
    before += resolved.frames[i].insideCorrected;
    after += resolved.frames[i].insideAfter;
    jumpResolved = std::max(jumpResolved, resolved.frames[i].maxJump);
    jumpRaw = std::max(jumpRaw, raw.frames[i].maxJump);
  }
  std::printf(
      "[ measured ] inside the driver: %ld before resolution, %ld after; largest jump "
      "%.5f resolved vs %.5f raw (skin offset %.4f)\n",
      before, after, jumpResolved, jumpRaw, options.evaluator.skinOffset);
  EXPECT_GT(before, 0) << "nothing to resolve on the sample: the test is vacuous";
  EXPECT_LT(after, before);
  // Moving a point to the surface changes it by at most its depth plus the offset, so the
  // frame-to-frame jump may grow by at most twice that; here it must not grow by more than
  // the offset (no popping).
  EXPECT_LE(jumpResolved, jumpRaw + 2 * options.evaluator.skinOffset);
}

// ---- Local-frame blending ----

TEST_F(FidelityTest, LocalBlendOfOneShapeIsTheBindingOfThatShape) {
  // One shape (a bent train pose), so every weight is 1: the local blend must rebuild exactly
  // that shape's cloth, bound at rest and carried to each shot frame - what transfer() of the
  // shape from its own pose gives.
  const Database db = buildSample(1, {40});
  ASSERT_EQ(db.shapeCount(), 1);
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const std::vector<int> frames = driver->frames();
  const int n = static_cast<int>(frames.size());
  const int vp = db.driverVertexCount(), vd = db.drivenVertexCount();
  TempDir dir;
  for (const bool useCl : {false, true}) {
    const Backends backends = useCl ? clBackends() : hostBackends();
    BakeOptions options;
    options.frames = frames;
    options.evaluator.blend = BlendMode::kLocal;
    options.evaluator.resolve = false;
    options.evaluator.strainLimit = 0.0;  // the blend alone
    options.outputPattern = dir.file(std::string(useCl ? "cl" : "host") + ".####.exr");
    bake(db, *driver, backends.view(), options);

    // The reference: bind the rest cloth at rest, transfer the shape's cloth from its pose.
    auto reference = makeHostClosest();
    reference->setSurface(db.driverMesh, BindingMask::all(vd));
    std::vector<SurfaceHit> restHits(vd);
    reference->closest(1, db.driverMesh.positions.data(), db.drivenMesh.positions.data(),
                       restHits.data());
    std::vector<SurfaceHit> hits(static_cast<std::size_t>(n) * vd);
    std::vector<float> from(static_cast<std::size_t>(n) * 3 * vp),
        points(static_cast<std::size_t>(n) * 3 * vd), expected(points.size());
    for (int i = 0; i < n; ++i) {
      std::copy(restHits.begin(), restHits.end(), hits.begin() + i * vd);
      std::copy_n(db.driverShapes.data(), 3 * vp, &from[i * 3 * vp]);
      std::copy_n(db.drivenShapes.data(), 3 * vd, &points[i * 3 * vd]);
    }
    const std::vector<float> to = readFrames(*driver, frames);
    reference->transfer(n, hits.data(), from.data(), to.data(), points.data(), expected.data());
    const double worst =
        worstRelativeDistance(expected, readBake(options.outputPattern, frames), n, vd);
    std::printf("[ measured ] %s local blend of one shape vs its transfer: %.3g of the diagonal\n",
                useCl ? "OpenCL" : "host", worst);
    EXPECT_LE(worst, testing::kDeviceVsHostRelTol);
  }
}

TEST_F(FidelityTest, LocalBlendReproducesDatabaseFrames) {
  const Database& db = sampleDatabase();
  const auto train = openPointCache(sample("train.driver.pc2"));
  TempDir dir;
  const Backends cl = clBackends();
  BakeOptions options;
  options.frames = {db.frames[3], db.frames[17]};
  options.evaluator.blend = BlendMode::kLocal;
  options.evaluator.resolve = false;
  options.evaluator.strainLimit = 0.0;  // the blend alone (see test_bake's database frames)
  options.outputPattern = dir.file("db.####.exr");
  const BakeResult result = bake(db, *train, cl.view(), options);
  const std::vector<float> baked = readBake(options.outputPattern, options.frames);
  const int vd = db.drivenVertexCount();
  const int shape[] = {3, 17};
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(result.frames[i].weights[shape[i]], 1.0, 1e-3);
    const std::vector<float> truth(db.drivenShapes.begin() + shape[i] * 3 * vd,
                                   db.drivenShapes.begin() + (shape[i] + 1) * 3 * vd);
    const std::vector<float> got(baked.begin() + i * 3 * vd, baked.begin() + (i + 1) * 3 * vd);
    EXPECT_LE(worstRelativeDistance(truth, got, 1, vd), 1e-3) << options.frames[i];
  }
}

// ---- Region-local weights ----

/// Brute-force signed ring distance of every vertex to the border of `set` (BFS from every
/// vertex separately, no shared state with the library).
std::vector<double> signedRings(const Mesh& mesh, const std::vector<char>& inside) {
  const int v = mesh.vertexCount();
  std::vector<std::vector<int>> next(v);
  for (int f = 0; f < mesh.faceCount(); ++f) {
    const int n = mesh.faceStart[f + 1] - mesh.faceStart[f];
    for (int i = 0; i < n; ++i) {
      const int a = mesh.faceVertices[mesh.faceStart[f] + i];
      const int b = mesh.faceVertices[mesh.faceStart[f] + (i + 1) % n];
      next[a].push_back(b);
      next[b].push_back(a);
    }
  }
  std::vector<double> s(v, 0.0);
  for (int start = 0; start < v; ++start) {
    std::vector<int> d(v, -1);
    std::queue<int> queue;
    d[start] = 0;
    queue.push(start);
    int found = -1;
    while (!queue.empty() && found < 0) {
      const int x = queue.front();
      queue.pop();
      if (inside[x] != inside[start]) {
        found = d[x];
        break;
      }
      for (int y : next[x]) {
        if (d[y] < 0) {
          d[y] = d[x] + 1;
          queue.push(y);
        }
      }
    }
    const double rings = found < 0 ? 1e9 : found - 0.5;
    s[start] = inside[start] ? rings : -rings;
  }
  return s;
}

TEST(RegionFalloff, IsAPartitionOfUnityAndMonotoneAcrossTheBorder) {
  const Mesh mesh = readObj(sample("driven_rest.obj"));
  const int v = mesh.vertexCount();
  const double middle = 0.5 * (mesh.positions.col(2).minCoeff() + mesh.positions.col(2).maxCoeff());
  std::vector<std::vector<int>> sets(2);
  std::vector<char> upper(v, 0);
  for (int i = 0; i < v; ++i) {
    upper[i] = mesh.positions(i, 2) >= middle;
    sets[upper[i] ? 0 : 1].push_back(i);
  }
  const std::vector<double> s = signedRings(mesh, upper);
  for (const int falloff : {0, 1, 4}) {
    const std::vector<float> mix = regionFalloff(mesh, sets, falloff);
    ASSERT_EQ(mix.size(), 2u * v);
    double worstSum = 0;
    int ramp = 0;
    for (int i = 0; i < v; ++i) {
      worstSum = std::max(worstSum, std::abs(double(mix[i]) + mix[v + i] - 1.0));
      EXPECT_GE(mix[i], 0.0f);
      EXPECT_LE(mix[i], 1.0f);
      // Inside the set beyond the falloff band: 1; outside beyond it: 0; a step when 0.
      if (s[i] >= falloff) {
        EXPECT_EQ(mix[i], 1.0f) << i;
      } else if (s[i] <= -falloff) {
        EXPECT_EQ(mix[i], 0.0f) << i;
      } else {
        ++ramp;
      }
    }
    EXPECT_LE(worstSum, testing::kPartitionOfUnityTol) << "falloff " << falloff;
    if (falloff > 0) {
      EXPECT_GT(ramp, 0) << "no vertex in the falloff band";
    }
    // Monotone: a vertex nearer the inside (larger signed distance) never has a smaller weight.
    std::vector<int> order(v);
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](int a, int b) { return s[a] < s[b]; });
    for (int j = 1; j < v; ++j) {
      EXPECT_LE(mix[order[j - 1]], mix[order[j]] + testing::kPartitionOfUnityTol)
          << "falloff " << falloff << " vertices " << order[j - 1] << ", " << order[j];
    }
  }
}

TEST(RegionFile, UncoveredVerticesFormTheRestRegionAndBadFilesAreInputErrors) {
  const Mesh driver = readObj(sample("driver_rest.obj"));
  const Mesh driven = readObj(sample("driven_rest.obj"));
  const RegionSet set = parseRegions(
      R"({"falloff": 1, "regions": [{"name": "a", "driver": {"vertices": ["0-99"]},
          "driven": {"vertices": [0, "1-49"]}, "comment": "a patch"}]})",
      "test.json", driver, driven);
  ASSERT_EQ(set.count(), 2);
  EXPECT_EQ(set.regions[1].name, "rest");
  EXPECT_EQ(static_cast<int>(set.regions[1].driverVertices.size()), driver.vertexCount());
  EXPECT_EQ(static_cast<int>(set.regions[0].drivenVertices.size()), 50);
  for (int v = 0; v < driven.vertexCount(); ++v) {
    EXPECT_NEAR(set.drivenMix[v] + set.drivenMix[driven.vertexCount() + v], 1.0,
                testing::kPartitionOfUnityTol);
  }
  auto expectInputError = [&](const std::string& text, const std::string& fragment) {
    try {
      parseRegions(text, "r.json", driver, driven);
      ADD_FAILURE() << "no error for " << text;
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kInput) << error.what();
      EXPECT_NE(std::string(error.what()).find(fragment), std::string::npos) << error.what();
    }
  };
  expectInputError(R"({"regions": [{"driver": "left_leg", "driven": "sleeve"}]})",
                   "regions[0].driver: the mesh has no group 'left_leg' (its groups: arm)");
  expectInputError(R"({"regions": []})", "non-empty \"regions\"");
  expectInputError(R"({"regions": [{"driver": "arm"}]})", "needs both");
  expectInputError(R"({"regions": [{"driver": "arm", "driven": "sleeve", "colour": 1}]})",
                   "unknown key 'colour'");
  expectInputError(R"({"regions": [{"name": "x", "driver": {"vertices": ["0-10"]}, "driven":
      "sleeve"}, {"name": "y", "driver": {"vertices": [5]}, "driven": {"vertices": [0]}}]})",
                   "driver vertex 5 is already in region 'x'");
  expectInputError(R"({"regions": [{"driver": {"vertices": [999999]}, "driven": "sleeve"}]})",
                   "outside 0-");
  expectInputError("{not json", "not valid JSON");
}

// ---- Temporal stability ----

TEST_F(FidelityTest, TemporalBoundHoldsAndChunkedBakesEqualTheSingleBake) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  const std::vector<int> frames = driver->frames();
  TempDir dir;
  const Backends cl = clBackends();
  BakeOptions options;
  options.frames = frames;
  options.batchFrames = 12;
  options.evaluator.maxWeightChange = 0.02;
  options.temporalWarmup = 6;
  options.threads = 2;
  options.outputPattern = dir.file("single.####.exr");
  const BakeResult single = bake(db, *driver, cl.view(), options);
  const int k = db.shapeCount();
  int bounded = 0;
  double unconstrainedChange = 0;
  for (std::size_t i = 1; i < single.frames.size(); ++i) {
    if (i % options.batchFrames == 0) {
      continue;  // the chain restarts (after its warm-up) at every batch
    }
    for (int s = 0; s < k; ++s) {
      const double change = std::abs(single.frames[i].weights[s] - single.frames[i - 1].weights[s]);
      EXPECT_LE(change, options.evaluator.maxWeightChange + testing::kWeightBoundTol)
          << "frame " << single.frames[i].frame << " shape " << s;
      bounded += change >= options.evaluator.maxWeightChange - 1e-9 ? 1 : 0;
    }
  }
  BakeOptions free = options;
  free.evaluator.maxWeightChange = 0;
  free.outputPattern = dir.file("free.####.exr");
  const BakeResult unconstrained = bake(db, *driver, cl.view(), free);
  for (std::size_t i = 1; i < unconstrained.frames.size(); ++i) {
    for (int s = 0; s < k; ++s) {
      unconstrainedChange = std::max(
          unconstrainedChange,
          std::abs(unconstrained.frames[i].weights[s] - unconstrained.frames[i - 1].weights[s]));
    }
  }
  std::printf(
      "[ measured ] temporal bound %.3f: %d shape-frames at the bound; largest change "
      "without it %.3f\n",
      options.evaluator.maxWeightChange, bounded, unconstrainedChange);
  EXPECT_GT(unconstrainedChange, options.evaluator.maxWeightChange) << "the bound is never active";
  EXPECT_GT(bounded, 0);

  // Farm chunks of two batches each, on one thread, give the single bake bit for bit.
  options.threads = 1;
  for (std::size_t first = 0; first < frames.size(); first += 2 * options.batchFrames) {
    BakeOptions chunk = options;
    chunk.frames.assign(frames.begin() + first,
                        frames.begin() + std::min(frames.size(), first + 2 * options.batchFrames));
    chunk.outputPattern = dir.file("chunked.####.exr");
    const BakeResult part = bake(db, *driver, cl.view(), chunk);
    for (std::size_t i = 0; i < part.frames.size(); ++i) {
      EXPECT_EQ(part.frames[i].weights, single.frames[first + i].weights)
          << "frame " << part.frames[i].frame;
    }
  }
  EXPECT_EQ(readBake(dir.file("single.####.exr"), frames),
            readBake(dir.file("chunked.####.exr"), frames));
}

// ---- Report and settings hash ----

TEST_F(FidelityTest, ReportAndSettingsHashRecordEveryFidelitySetting) {
  const Database& db = sampleDatabase();
  const auto driver = openPointCache(sample("test.driver.pc2"));
  TempDir dir;
  const Backends host = hostBackends();
  BakeOptions options;
  options.frames = {1, 2, 3};
  options.outputPattern = dir.file("a.####.exr");
  options.reportPath = dir.file("a.json");
  const std::uint64_t base = bake(db, *driver, host.view(), options).settingsHash;
  std::ifstream in(options.reportPath);
  const nlohmann::json report = nlohmann::json::parse(in);
  const nlohmann::json& settings = report.at("settings");
  EXPECT_EQ(settings.at("align"), "rigid");
  EXPECT_EQ(settings.at("align_group"), "all");
  EXPECT_EQ(settings.at("blend"), "local");
  EXPECT_EQ(settings.at("resolve"), true);
  EXPECT_DOUBLE_EQ(settings.at("skin_offset").get<double>(), options.evaluator.skinOffset);
  EXPECT_DOUBLE_EQ(settings.at("exit_fade").get<double>(), options.evaluator.exitFade);
  EXPECT_EQ(settings.at("max_weight_change"), 0.0);
  for (const auto& frame : report.at("frames")) {
    EXPECT_TRUE(frame.contains("align_rotation"));
    EXPECT_TRUE(frame.contains("inside_corrected"));
    EXPECT_TRUE(frame.contains("resolved"));
  }
  std::vector<std::function<void(BakeOptions&)>> changes = {
      [](BakeOptions& o) { o.evaluator.align = AlignMode::kNone; },
      [](BakeOptions& o) { o.evaluator.alignGroup = "0-500"; },
      [](BakeOptions& o) { o.evaluator.align = AlignMode::kRigidAll; },
      [](BakeOptions& o) { o.evaluator.blend = BlendMode::kWorld; },
      [](BakeOptions& o) { o.evaluator.resolve = false; },
      [](BakeOptions& o) { o.evaluator.skinOffset = 0.004; },
      [](BakeOptions& o) { o.evaluator.exitFade = 0.0; },
      [](BakeOptions& o) { o.evaluator.exitFade = 0.3; },
      [](BakeOptions& o) { o.evaluator.maxWeightChange = 0.1; },
  };
  for (std::size_t c = 0; c < changes.size(); ++c) {
    BakeOptions changed = options;
    changes[c](changed);
    changed.reportPath.clear();
    changed.outputPattern = dir.file("c" + std::to_string(c) + ".####.exr");
    EXPECT_NE(bake(db, *driver, host.view(), changed).settingsHash, base) << "change " << c;
  }
}

}  // namespace
}  // namespace drivenshape
