// SPDX-License-Identifier: Apache-2.0
// drivenshape eval: the library (evaluateShot, on the host and the OpenCL closest-triangle
// search) and the command on a closed cube that travels and turns, where every figure is known
// analytically, and the command on the bundled sleeve (the binding baseline against a real
// `bake --weights bind --no-resolve --strain-limit 0`, the truth against itself, the error against
// a brute-force computation, and the error messages).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <tuple>
#include <utility>

#include <Eigen/Geometry>

#include <drivenshape/error.h>
#include <drivenshape/evaluate.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

#include "atomic_file.h"
#include "closest.h"

#include "cl_backends.h"

#include "cli_test_util.h"
#include "io_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

namespace fs = std::filesystem;
using testing::CliRun;
using testing::expectThrows;
using testing::kEvalDepthRelTol;
using testing::kEvalErrorRelTol;
using testing::kStrainTol;
using testing::kTransferRelTol;
using testing::referenceSpearman;
using testing::runCli;
using testing::sample;
using testing::slurp;
using testing::TempDir;
using testing::writeTextFile;

// ---- The cube scene ----

/// The closed cube [-1, 1]^3, each side split into n x n outward-facing quads.
Mesh cubeMesh(int n) {
  Mesh mesh;
  std::map<std::tuple<int, int, int>, int> ids;  // lattice point (0..n per axis) -> vertex
  std::vector<Eigen::Vector3f> points;
  auto vertex = [&](int x, int y, int z) {
    const auto key = std::make_tuple(x, y, z);
    const auto found = ids.find(key);
    if (found != ids.end()) {
      return found->second;
    }
    const int id = static_cast<int>(points.size());
    ids[key] = id;
    points.emplace_back(2.0f * x / n - 1.0f, 2.0f * y / n - 1.0f, 2.0f * z / n - 1.0f);
    return id;
  };
  mesh.faceStart.push_back(0);
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          // Corners in the side's (u, v) plane; the fixed axis is 0 or n.
          int corner[4][3];
          const int uv[4][2] = {{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}};
          for (int c = 0; c < 4; ++c) {
            corner[c][axis] = side * n;
            corner[c][(axis + 1) % 3] = uv[c][0];
            corner[c][(axis + 2) % 3] = uv[c][1];
          }
          int quad[4];
          for (int c = 0; c < 4; ++c) {
            quad[c] = vertex(corner[c][0], corner[c][1], corner[c][2]);
          }
          // (u, v, axis) is right-handed, so u x v points along +axis: reverse on side 0.
          if (side == 0) {
            std::swap(quad[1], quad[3]);
          }
          mesh.faceVertices.insert(mesh.faceVertices.end(), quad, quad + 4);
          mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
          mesh.faceGroup.push_back(0);
        }
      }
    }
  }
  mesh.groupNames = {"cube"};
  mesh.positions.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v) {
    mesh.positions.row(static_cast<Eigen::Index>(v)) = points[v].transpose();
  }
  mesh.triangulate();
  return mesh;
}

/// Cloth points as a mesh of separate triangles (3 vertices each), for OBJ files.
Mesh pointMesh(const std::vector<Eigen::Vector3d>& points) {
  Mesh mesh;
  mesh.faceStart.push_back(0);
  for (std::size_t v = 0; v + 2 < points.size(); v += 3) {
    for (int c = 0; c < 3; ++c) {
      mesh.faceVertices.push_back(static_cast<int>(v) + c);
    }
    mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
    mesh.faceGroup.push_back(0);
  }
  mesh.groupNames = {"cloth"};
  mesh.positions.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v) {
    mesh.positions.row(static_cast<Eigen::Index>(v)) = points[v].cast<float>().transpose();
  }
  mesh.triangulate();
  return mesh;
}

double linf(const Eigen::Vector3d& p) {
  return p.cwiseAbs().maxCoeff();
}

/// A cube that travels and turns over frames 1..F; cloth given in the cube's own coordinates,
/// where inside means |p|_inf < 1 and the depth of an inside point is 1 - |p|_inf.
struct CubeScene {
  static constexpr int kFrames = 6;
  static constexpr int kClothVertices = 240;  // a multiple of 3 (pointMesh)
  Mesh driver = cubeMesh(2);
  std::vector<Eigen::Vector3d> restLocal;  // the rest cloth (frame 0: no motion)
  std::vector<std::vector<Eigen::Vector3d>> truthLocal, bakeLocal;  // per frame

  Eigen::Isometry3d motion(int frame) const {
    Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
    m.translate(Eigen::Vector3d(0.7 * frame, -0.3 * frame, 0.2 * frame));
    m.rotate(Eigen::AngleAxisd(0.35 * frame, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()));
    return m;
  }

  explicit CubeScene(std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    // A point whose |p|_inf lies in [lo, hi], away from the surface.
    auto pointAt = [&](double lo, double hi) {
      for (;;) {
        const Eigen::Vector3d p(unit(rng), unit(rng), unit(rng));
        const Eigen::Vector3d q = p * (lo + (hi - lo) * (0.5 + 0.5 * unit(rng))) / linf(p);
        if (linf(q) >= lo && linf(q) <= hi) {
          return q;
        }
      }
    };
    auto cloth = [&](double insideShare) {
      std::vector<Eigen::Vector3d> points;
      std::uniform_real_distribution<double> coin(0.0, 1.0);
      for (int v = 0; v < kClothVertices; ++v) {
        points.push_back(coin(rng) < insideShare ? pointAt(0.3, 0.97) : pointAt(1.03, 1.6));
      }
      return points;
    };
    restLocal = cloth(0.1);
    for (int f = 1; f <= kFrames; ++f) {
      truthLocal.push_back(restLocal);  // the truth follows the cube rigidly
      bakeLocal.push_back(cloth(0.05 * f));
    }
  }

  /// F x 3V world positions (frame-major) of per-frame local points.
  std::vector<float> world(const std::vector<std::vector<Eigen::Vector3d>>& local) const {
    std::vector<float> out;
    for (int f = 1; f <= kFrames; ++f) {
      for (const Eigen::Vector3d& p : local[f - 1]) {
        const Eigen::Vector3d x = motion(f) * p;
        out.insert(out.end(), {float(x.x()), float(x.y()), float(x.z())});
      }
    }
    return out;
  }
  std::vector<float> driverFrames() const {
    std::vector<std::vector<Eigen::Vector3d>> local(kFrames);
    for (auto& frame : local) {
      for (Eigen::Index v = 0; v < driver.positions.rows(); ++v) {
        frame.push_back(driver.positions.row(v).transpose().cast<double>());
      }
    }
    return world(local);
  }
  /// Scene scale S for tolerances: the largest coordinate over all frames, at least the cube's
  /// diagonal.
  double scale() const {
    double s = 2.0 * std::sqrt(3.0);
    for (float x : driverFrames()) {
      s = std::max(s, double(std::fabs(x)));
    }
    return s;
  }
};

struct Analytic {
  int inside = 0;
  double depth = 0.0;
};
Analytic analytic(const std::vector<Eigen::Vector3d>& local) {
  Analytic a;
  for (const Eigen::Vector3d& p : local) {
    if (linf(p) < 1.0) {
      ++a.inside;
      a.depth = std::max(a.depth, 1.0 - linf(p));
    }
  }
  return a;
}

/// Brute-force error and largest move between two V x 3 float blocks, in double.
struct Distances {
  double mean = 0, rms = 0, max = 0;
};
Distances distances(const float* a, const float* b, int vertices) {
  Distances d;
  for (int v = 0; v < vertices; ++v) {
    const double e = std::sqrt(std::pow(double(a[3 * v]) - b[3 * v], 2) +
                               std::pow(double(a[3 * v + 1]) - b[3 * v + 1], 2) +
                               std::pow(double(a[3 * v + 2]) - b[3 * v + 2], 2));
    d.mean += e / vertices;
    d.rms += e * e / vertices;
    d.max = std::max(d.max, e);
  }
  d.rms = std::sqrt(d.rms);
  return d;
}

void expectRel(double value, double expected, double tolerance, const std::string& what) {
  EXPECT_LE(std::abs(value - expected), tolerance * std::max(std::abs(expected), 1e-300))
      << what << ": " << value << " vs " << expected << " (relative tolerance " << tolerance << ")";
}

/// Brute-force strain figures of cloth frames against the rest cloth of the cube scene: its
/// mesh (pointMesh) is separate triangles (3k, 3k + 1, 3k + 2), so its edges are those three
/// pairs of every triangle. Every |strain| is kept and sorted; the 95th percentile is the value
/// at rank ceil(0.95 n), which is n - n / 20 for the n here (multiples of 20).
StrainFigures bruteStrain(const std::vector<float>& rest, const std::vector<const float*>& frames,
                          int vertices) {
  std::vector<double> all;
  for (const float* p : frames) {
    for (int t = 0; t + 2 < vertices; t += 3) {
      for (const auto& [a, b] :
           {std::pair{t, t + 1}, std::pair{t + 1, t + 2}, std::pair{t, t + 2}}) {
        const double now =
            Eigen::Vector3d(double(p[3 * b]) - p[3 * a], double(p[3 * b + 1]) - p[3 * a + 1],
                            double(p[3 * b + 2]) - p[3 * a + 2])
                .norm();
        const double before = Eigen::Vector3d(double(rest[3 * b]) - rest[3 * a],
                                              double(rest[3 * b + 1]) - rest[3 * a + 1],
                                              double(rest[3 * b + 2]) - rest[3 * a + 2])
                                  .norm();
        all.push_back(std::abs(now / before - 1.0));
      }
    }
  }
  EXPECT_EQ(all.size() % 20, 0u);
  StrainFigures f;
  f.values = static_cast<long long>(all.size());
  for (double value : all) {
    f.mean += value / double(all.size());
    f.overShare += value > 0.1 ? 1.0 / double(all.size()) : 0.0;
  }
  std::sort(all.begin(), all.end());
  f.p95 = all[all.size() - all.size() / 20 - 1];
  return f;
}

void expectStrain(const StrainFigures& value, const StrainFigures& expected,
                  const std::string& what) {
  EXPECT_EQ(value.values, expected.values) << what;
  expectRel(value.mean, expected.mean, kEvalErrorRelTol, what + " strain mean");
  expectRel(value.p95, expected.p95, kEvalErrorRelTol, what + " strain p95");
  EXPECT_NEAR(value.overShare, expected.overShare, 1e-12) << what << " strain share over 10%";
}

/// Files for the cube scene in `dir`: driver.obj, cloth.obj, driver.pc2, truth.pc2, bake.pc2.
void writeCubeFiles(const CubeScene& scene, const TempDir& dir) {
  writeObj(dir.file("driver.obj"), scene.driver);
  writeObj(dir.file("cloth.obj"), pointMesh(scene.restLocal));
  const std::vector<float> driver = scene.driverFrames();
  const std::vector<float> truth = scene.world(scene.truthLocal);
  const std::vector<float> bake = scene.world(scene.bakeLocal);
  writePc2(dir.file("driver.pc2"), scene.driver.vertexCount(), 1.0f, CubeScene::kFrames,
           driver.data());
  writePc2(dir.file("truth.pc2"), CubeScene::kClothVertices, 1.0f, CubeScene::kFrames,
           truth.data());
  writePc2(dir.file("bake.pc2"), CubeScene::kClothVertices, 1.0f, CubeScene::kFrames, bake.data());
}

/// The strain of the cube scene's bake and truth, per frame and over the shot, against
/// bruteStrain; the baseline carries the rest cloth rigidly, so its strain is only the
/// transfer's float rounding (well under 0.1%).
void checkCubeStrain(const CubeScene& scene, const ShotEvaluation& e) {
  const int vd = CubeScene::kClothVertices;
  const Mesh cloth = pointMesh(scene.restLocal);
  const std::vector<float> rest(cloth.positions.data(),
                                cloth.positions.data() + cloth.positions.size());
  const std::vector<float> truth = scene.world(scene.truthLocal);
  const std::vector<float> bake = scene.world(scene.bakeLocal);
  ASSERT_TRUE(e.strain);
  EXPECT_EQ(e.edgeCount, vd);  // three edges per triangle of three vertices
  std::vector<const float*> bakeFrames, truthFrames;
  for (int f = 0; f < CubeScene::kFrames; ++f) {
    const std::string where = "frame " + std::to_string(f + 1);
    bakeFrames.push_back(&bake[f * 3 * vd]);
    truthFrames.push_back(&truth[f * 3 * vd]);
    expectStrain(e.bake.frames[f].strain, bruteStrain(rest, {bakeFrames.back()}, vd),
                 where + " bake");
    expectStrain(e.truth.frames[f].strain, bruteStrain(rest, {truthFrames.back()}, vd),
                 where + " truth");
  }
  expectStrain(e.bake.strain, bruteStrain(rest, bakeFrames, vd), "shot bake");
  expectStrain(e.truth.strain, bruteStrain(rest, truthFrames, vd), "shot truth");
  EXPECT_GT(e.bake.strain.overShare, 0.5);  // random cloth: the figures test something
  EXPECT_LT(e.baseline.strain.p95, 1e-3);
}

/// Checks an evaluation of the cube scene against the analytic figures and brute force.
void checkCubeEvaluation(const CubeScene& scene, const ShotEvaluation& e) {
  const int vd = CubeScene::kClothVertices;
  const double S = scene.scale();
  const std::vector<float> truth = scene.world(scene.truthLocal);
  const std::vector<float> bake = scene.world(scene.bakeLocal);
  ASSERT_EQ(e.bake.frames.size(), std::size_t(CubeScene::kFrames));
  ASSERT_TRUE(e.penetrations);
  ASSERT_TRUE(e.hasBaseline);
  double sum = 0.0, squares = 0.0, bakeJump = -1.0, truthJump = -1.0;
  for (int f = 0; f < CubeScene::kFrames; ++f) {
    const std::string where = "frame " + std::to_string(f + 1);
    const Distances error = distances(&truth[f * 3 * vd], &bake[f * 3 * vd], vd);
    const ClothFrameMetrics& b = e.bake.frames[f];
    const ClothFrameMetrics& t = e.truth.frames[f];
    const ClothFrameMetrics& l = e.baseline.frames[f];
    EXPECT_EQ(b.frame, f + 1);
    expectRel(b.error.mean, error.mean, kEvalErrorRelTol, where + " mean");
    expectRel(b.error.rms, error.rms, kEvalErrorRelTol, where + " rms");
    expectRel(b.error.max, error.max, kEvalErrorRelTol, where + " max");
    sum += error.mean * vd;
    squares += error.rms * error.rms * vd;
    // The truth against itself.
    EXPECT_EQ(t.error.mean, 0.0) << where;
    EXPECT_EQ(t.error.max, 0.0) << where;
    // Penetrations: the analytic counts and depths.
    const Analytic bakeInside = analytic(scene.bakeLocal[f]);
    const Analytic truthInside = analytic(scene.truthLocal[f]);
    EXPECT_EQ(b.inside, bakeInside.inside) << where;
    EXPECT_NEAR(b.maxDepth, bakeInside.depth, kEvalDepthRelTol * S) << where;
    EXPECT_EQ(t.inside, truthInside.inside) << where;
    EXPECT_NEAR(t.maxDepth, truthInside.depth, kEvalDepthRelTol * S) << where;
    // The baseline carries the rest cloth rigidly with the cube: it is the truth, to the
    // transfer's float rounding, and so are its penetrations.
    EXPECT_LE(l.error.max, kTransferRelTol * S) << where;
    EXPECT_EQ(l.inside, truthInside.inside) << where;
    EXPECT_NEAR(l.maxDepth, truthInside.depth, kEvalDepthRelTol * S) << where;
    // Jumps: none on the first frame, then the brute-force largest move.
    if (f == 0) {
      EXPECT_EQ(b.jump, -1.0);
      EXPECT_EQ(t.jump, -1.0);
    } else {
      const Distances bakeMove = distances(&bake[(f - 1) * 3 * vd], &bake[f * 3 * vd], vd);
      const Distances truthMove = distances(&truth[(f - 1) * 3 * vd], &truth[f * 3 * vd], vd);
      expectRel(b.jump, bakeMove.max, kEvalErrorRelTol, where + " bake jump");
      expectRel(t.jump, truthMove.max, kEvalErrorRelTol, where + " truth jump");
      EXPECT_NEAR(l.jump, truthMove.max, 2.0 * kTransferRelTol * S) << where;
      bakeJump = std::max(bakeJump, bakeMove.max);
      truthJump = std::max(truthJump, truthMove.max);
    }
  }
  checkCubeStrain(scene, e);
  const double total = double(vd) * CubeScene::kFrames;
  expectRel(e.bake.mean, sum / total, kEvalErrorRelTol, "overall mean");
  expectRel(e.bake.rms, std::sqrt(squares / total), kEvalErrorRelTol, "overall rms");
  expectRel(e.bake.maxJump, bakeJump, kEvalErrorRelTol, "largest bake jump");
  expectRel(e.truth.maxJump, truthJump, kEvalErrorRelTol, "largest truth jump");
  EXPECT_EQ(e.truth.mean, 0.0);
  EXPECT_LE(e.baseline.max, kTransferRelTol * S);
}

/// The cube scene's files in `dir` (writeCubeFiles), read back.
struct CubeFiles {
  explicit CubeFiles(const TempDir& dir)
      : driverMesh(readObj(dir.file("driver.obj"))),
        drivenMesh(readObj(dir.file("cloth.obj"))),
        truth(openPointCache(dir.file("truth.pc2"))),
        bake(openPointCache(dir.file("bake.pc2"))),
        driver(openPointCache(dir.file("driver.pc2"))) {}
  CubeFiles(const CubeFiles&) = delete;  // input() points into this object
  CubeFiles& operator=(const CubeFiles&) = delete;

  /// The evaluation of the bake against the truth with the baseline, over these files.
  ShotEvaluationInput input() const {
    ShotEvaluationInput in;
    in.truth = truth.get();
    in.bake = bake.get();
    in.driver = driver.get();
    in.driverMesh = &driverMesh;
    in.drivenMesh = &drivenMesh;
    in.baseline = true;
    return in;
  }

  Mesh driverMesh;
  Mesh drivenMesh;
  std::unique_ptr<PointCacheReader> truth;
  std::unique_ptr<PointCacheReader> bake;
  std::unique_ptr<PointCacheReader> driver;
};

/// Evaluates the cube scene from files with `closest`.
ShotEvaluation evaluateCube(const TempDir& dir, ClosestBackend& closest, int batch) {
  const CubeFiles files(dir);
  ShotEvaluationInput input = files.input();
  input.batch = batch;
  return evaluateShot(input, {1, 2, 3, 4, 5, 6}, closest);
}

TEST(EvalShot, CubeFiguresMatchTheAnalyticTruthOnTheHost) {
  const CubeScene scene(testing::testSeed());
  TempDir dir;
  writeCubeFiles(scene, dir);
  const auto host = makeHostClosest();
  // Batches of 4 frames: the second batch's first jump crosses the batch boundary.
  const ShotEvaluation e = evaluateCube(dir, *host, 4);
  checkCubeEvaluation(scene, e);
  std::printf(
      "[ measured ] cube: bake %.1f inside/frame (deepest %.4f), truth %.1f, baseline "
      "error max %.3g (scale %.3g)\n",
      e.bake.meanInside, e.bake.maxDepth, e.truth.meanInside, e.baseline.max, scene.scale());
  // The generator must produce penetrations, or the counts test nothing.
  EXPECT_GT(e.bake.maxInside, 5);
  EXPECT_GT(e.truth.maxInside, 5);
}

class EvalShotCl : public testing::OpenClTest {};

TEST_F(EvalShotCl, CubeFiguresMatchTheAnalyticTruthOnOpenCl) {
  const CubeScene scene(testing::testSeed());
  TempDir dir;
  writeCubeFiles(scene, dir);
  const auto cl = makeClClosest(context(), device(), queue());
  checkCubeEvaluation(scene, evaluateCube(dir, *cl, 16));
}

TEST(EvalShot, BadInputsGiveClearErrors) {
  const CubeScene scene(testing::testSeed());
  TempDir dir;
  writeCubeFiles(scene, dir);
  const CubeFiles files(dir);
  const Mesh& driverMesh = files.driverMesh;
  const Mesh& drivenMesh = files.drivenMesh;
  const auto host = makeHostClosest();
  auto base = [&] {
    ShotEvaluationInput input = files.input();
    input.driverMeshName = "driver.obj";
    input.drivenMeshName = "cloth.obj";
    return input;
  };
  ShotEvaluationInput input = base();
  expectThrows([&] { evaluateShot(input, {}, *host); }, ErrorCode::kUsage, "empty");
  expectThrows([&] { evaluateShot(input, {1, 7}, *host); }, ErrorCode::kInput, "no frame 7");
  input.bake = files.driver.get();  // 26 vertices against 240
  expectThrows([&] { evaluateShot(input, {1}, *host); }, ErrorCode::kInput, "vertices");
  input = base();
  input.driverMesh = &drivenMesh;  // the wrong rest mesh for the driver cache
  expectThrows([&] { evaluateShot(input, {1}, *host); }, ErrorCode::kInput, "driver cache");
  input = base();
  input.drivenMesh = &driverMesh;  // the wrong rest mesh for the cloth
  expectThrows([&] { evaluateShot(input, {1}, *host); }, ErrorCode::kInput, "cloth's rest mesh");
  input = base();
  input.driverMesh = nullptr;
  expectThrows([&] { evaluateShot(input, {1}, *host); }, ErrorCode::kUsage, "--driver-mesh");
  input = base();
  input.drivenMesh = nullptr;
  expectThrows([&] { evaluateShot(input, {1}, *host); }, ErrorCode::kUsage, "--driven-mesh");
  input = base();
  input.driver = nullptr;
  expectThrows([&] { evaluateShot(input, {1}, *host); }, ErrorCode::kUsage, "--driver");
}

// ---- The command ----

nlohmann::json readJson(const std::string& path) {
  return nlohmann::json::parse(slurp(path));
}

/// One error line naming `fragment`, with exit code `code`.
void expectCliError(const CliRun& r, int code, const std::string& fragment) {
  EXPECT_EQ(r.code, code) << r.err;
  EXPECT_NE(r.err.find(fragment), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST(EvalCommand, CubeTableAndJsonMatchTheAnalyticTruth) {
  const CubeScene scene(testing::testSeed());
  TempDir dir;
  writeCubeFiles(scene, dir);
  const CliRun r =
      runCli(dir, {"eval", "--truth", dir.file("truth.pc2"), "--bake", dir.file("bake.pc2"),
                   "--frames", "1-6", "--driver", dir.file("driver.pc2"), "--driver-mesh",
                   dir.file("driver.obj"), "--driven-mesh", dir.file("cloth.obj"), "--baseline",
                   "--per-frame", "--json", dir.file("eval.json")});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* row : {"error mean", "inside driver / frame", "deepest penetration",
                          "largest frame jump", "baseline", "overall over 6 frames x 240",
                          "lengths (errors, depths, jumps) in scene units"}) {
    EXPECT_NE(r.out.find(row), std::string::npos) << row << "\n" << r.out;
  }
  const nlohmann::json j = readJson(dir.file("eval.json"));
  const double S = scene.scale();
  ASSERT_EQ(j["frames"].size(), std::size_t(CubeScene::kFrames));
  const std::vector<float> truth = scene.world(scene.truthLocal);
  const std::vector<float> bake = scene.world(scene.bakeLocal);
  const int vd = CubeScene::kClothVertices;
  for (int f = 0; f < CubeScene::kFrames; ++f) {
    const nlohmann::json& frame = j["frames"][f];
    const Distances error = distances(&truth[f * 3 * vd], &bake[f * 3 * vd], vd);
    expectRel(frame["mean"].get<double>(), error.mean, kEvalErrorRelTol, "json mean");
    expectRel(frame["bake"]["max"].get<double>(), error.max, kEvalErrorRelTol, "json max");
    const Analytic bakeInside = analytic(scene.bakeLocal[f]);
    const Analytic truthInside = analytic(scene.truthLocal[f]);
    EXPECT_EQ(frame["bake"]["inside"].get<int>(), bakeInside.inside);
    EXPECT_NEAR(frame["bake"]["max_depth"].get<double>(), bakeInside.depth, kEvalDepthRelTol * S);
    EXPECT_EQ(frame["truth"]["inside"].get<int>(), truthInside.inside);
    EXPECT_EQ(frame["baseline"]["inside"].get<int>(), truthInside.inside);
    EXPECT_LE(frame["baseline"]["max"].get<double>(), kTransferRelTol * S);
    EXPECT_EQ(frame["bake"]["jump"].is_null(), f == 0);
  }
  EXPECT_TRUE(j["penetrations"].get<bool>());
  EXPECT_TRUE(j["baseline"].get<bool>());
  EXPECT_EQ(j["summary"]["truth"]["mean_inside"].get<double>(),
            j["summary"]["baseline"]["mean_inside"].get<double>());
}

TEST(EvalCommand, SleeveBaselineEqualsTheBindBakeAndTruthAgainstItself) {
  TempDir dir;
  const std::string db = testing::buildPoseDb(dir);
  CliRun r;
  const std::string frames = "1-13x4";
  fs::create_directories(dir.file("bind"));
  r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", frames,
                   "--weights", "bind", "--no-resolve", "--strain-limit", "0", "--device", "host",
                   "--quiet", "-o", dir.file("bind/sleeve.####.exr")});
  ASSERT_EQ(r.code, 0) << r.err;

  // The bind bake judged with its own baseline beside it: the two columns are one computation.
  r = runCli(
      dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake",
            dir.file("bind/sleeve.####.exr"), "--frames", frames, "--driver",
            sample("test.driver.pc2"), "--db", db, "--baseline", "--json", dir.file("bind.json")});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json bind = readJson(dir.file("bind.json"));
  // --db gives the cloth's rest mesh: strain is measured by default, the sleeve's 4444 quad
  // sides (2200 quads).
  EXPECT_TRUE(bind["strain"].get<bool>());
  EXPECT_EQ(bind["edges"].get<int>(), 4444);
  EXPECT_NE(r.out.find("mean |strain|"), std::string::npos) << r.out;
  for (const char* key : {"mean", "rms", "max", "max_jump", "mean_inside", "max_depth",
                          "strain_mean", "strain_p95", "strain_share_over_10pct"}) {
    ASSERT_TRUE(bind["summary"]["baseline"].contains(key)) << key;
    EXPECT_EQ(bind["summary"]["baseline"][key], bind["summary"]["bake"][key]) << key;
  }
  for (const nlohmann::json& frame : bind["frames"]) {
    EXPECT_EQ(frame["baseline"], frame["bake"]) << frame.dump();
  }

  // The error against an independent brute-force computation over the files.
  const auto truthCache = openPointCache(sample("test.driven.pc2"));
  const auto bakeCache = openPointCache(dir.file("bind/sleeve.####.exr"));
  const int vd = truthCache->vertexCount();
  std::vector<float> a(3 * std::size_t(vd)), b(a.size());
  double sum = 0.0, largest = 0.0;
  int count = 0;
  for (int frame : {1, 5, 9, 13}) {
    truthCache->readFrame(frame, a.data());
    bakeCache->readFrame(frame, b.data());
    const Distances d = distances(a.data(), b.data(), vd);
    sum += d.mean;
    largest = std::max(largest, d.max);
    ++count;
  }
  expectRel(bind["mean"].get<double>(), sum / count, kEvalErrorRelTol, "sleeve mean");
  expectRel(bind["max"].get<double>(), largest, kEvalErrorRelTol, "sleeve max");

  // The truth against itself: no error, the same jumps and penetrations on both sides.
  r = runCli(dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake",
                   sample("test.driven.pc2"), "--frames", frames, "--driver",
                   sample("test.driver.pc2"), "--db", db, "--json", dir.file("self.json")});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json self = readJson(dir.file("self.json"));
  EXPECT_EQ(self["mean"].get<double>(), 0.0);
  EXPECT_EQ(self["rms"].get<double>(), 0.0);
  EXPECT_EQ(self["max"].get<double>(), 0.0);
  EXPECT_GT(self["summary"]["truth"]["max_jump"].get<double>(), 0.0);
  EXPECT_EQ(self["summary"]["bake"]["max_jump"], self["summary"]["truth"]["max_jump"]);
  for (const nlohmann::json& frame : self["frames"]) {
    EXPECT_EQ(frame["bake"]["inside"], frame["truth"]["inside"]);
    EXPECT_EQ(frame["bake"]["max_depth"], frame["truth"]["max_depth"]);
    EXPECT_EQ(frame["bake"]["jump"], frame["truth"]["jump"]);
  }
  EXPECT_NE(r.out.find("/ truth's"), std::string::npos) << r.out;
  for (const char* key : {"strain_mean", "strain_p95", "strain_share_over_10pct"}) {
    EXPECT_GT(self["summary"]["truth"][key].get<double>(), 0.0) << key;
    EXPECT_EQ(self["summary"]["bake"][key], self["summary"]["truth"][key]) << key;
  }

  // --db alone (no driver): the strain, without penetrations.
  r = runCli(dir,
             {"eval", "--truth", sample("test.driven.pc2"), "--bake", sample("test.driven.pc2"),
              "--frames", frames, "--db", db, "--json", dir.file("strain_only.json")});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json strainOnly = readJson(dir.file("strain_only.json"));
  EXPECT_TRUE(strainOnly["strain"].get<bool>());
  EXPECT_FALSE(strainOnly["penetrations"].get<bool>());
  EXPECT_EQ(strainOnly["summary"]["truth"]["strain_p95"], self["summary"]["truth"]["strain_p95"]);
}

// bake --strain-limit (issue 43): the bake's strain, as eval measures it against the rest cloth,
// falls well below the default bake's, the penetration resolution after the limit still leaves
// no vertex inside the driver, and the report says the limit ran.
TEST(EvalCommand, StrainLimitLowersTheBakesStrainAndKeepsTheClothOutside) {
  TempDir dir;
  const std::string db = testing::buildPoseDb(dir);
  const std::string frames = "1-48x4";
  const auto bakeAndEval = [&](const std::string& name, std::vector<std::string> extra) {
    fs::create_directories(dir.file(name));
    std::vector<std::string> args = {"bake", "--db", db, "--driver", sample("test.driver.pc2")};
    for (const std::string& word :
         {std::string("--frames"), frames, std::string("--device"), std::string("host"),
          std::string("--quiet"), std::string("-o"), dir.file(name + "/sleeve.####.exr"),
          std::string("--report"), dir.file(name + ".report.json")}) {
      args.push_back(word);
    }
    args.insert(args.end(), extra.begin(), extra.end());
    CliRun r = runCli(dir, args);
    EXPECT_EQ(r.code, 0) << r.err;
    r = runCli(dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake",
                     dir.file(name + "/sleeve.####.exr"), "--frames", frames, "--driver",
                     sample("test.driver.pc2"), "--db", db, "--json", dir.file(name + ".json")});
    EXPECT_EQ(r.code, 0) << r.err;
    return std::make_pair(readJson(dir.file(name + ".report.json")),
                          readJson(dir.file(name + ".json"))["summary"]["bake"]);
  };
  const auto [plainReport, plain] =
      bakeAndEval("plain", {"--strain-limit", "0", "--exit-fade", "0.15"});
  const auto [limitedReport, limited] = bakeAndEval("limited", {"--strain-limit", "0.05"});
  std::printf("  mean |strain| %.3f%% -> %.3f%%, p95 %.3f%% -> %.3f%%, > 10%% %.3f%% -> %.3f%%\n",
              100 * plain["strain_mean"].get<double>(), 100 * limited["strain_mean"].get<double>(),
              100 * plain["strain_p95"].get<double>(), 100 * limited["strain_p95"].get<double>(),
              100 * plain["strain_share_over_10pct"].get<double>(),
              100 * limited["strain_share_over_10pct"].get<double>());
  EXPECT_LT(limited["strain_mean"].get<double>(), 0.6 * plain["strain_mean"].get<double>());
  EXPECT_LT(limited["strain_p95"].get<double>(), 0.6 * plain["strain_p95"].get<double>());
  EXPECT_LT(limited["strain_share_over_10pct"].get<double>(),
            0.5 * plain["strain_share_over_10pct"].get<double>());
  // The resolution ran after the limit: nothing inside, by the bake's audit and by eval's.
  for (const nlohmann::json& frame : limitedReport["frames"]) {
    EXPECT_EQ(frame["inside_after"].get<int>(), 0) << frame["frame"];
  }
  EXPECT_EQ(limited["mean_inside"].get<double>(), 0.0);
  EXPECT_EQ(limitedReport["settings"]["strain_limit"].get<double>(), 0.05);
  EXPECT_EQ(limitedReport["settings"]["strain_iterations"].get<int>(), 24);
  EXPECT_EQ(plainReport["settings"]["strain_limit"].get<double>(), 0.0);
  const nlohmann::json& stages = limitedReport["settings"]["stages"];
  EXPECT_NE(std::find(stages.begin(), stages.end(), "strain"), stages.end()) << stages.dump();
  EXPECT_NE(limitedReport["settings_hash"], plainReport["settings_hash"]);
}

TEST(EvalCommand, OldFlagsStillWork) {
  TempDir dir;
  const CliRun r = runCli(
      dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake", sample("test.driven.pc2"),
            "--frames", "1-3", "--per-frame", "--json", dir.file("eval.json")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("overall over 3 frames x 2244 vertices: mean 0, rms 0, max 0"),
            std::string::npos)
      << r.out;
  const nlohmann::json j = readJson(dir.file("eval.json"));
  for (const char* key : {"truth", "bake", "vertices", "mean", "rms", "max", "max_frame"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_FALSE(j["penetrations"].get<bool>());
  EXPECT_EQ(j["frames"][0]["max_vertex"].get<int>(), 0);
  // No cloth rest mesh: no strain, and the output says so.
  EXPECT_FALSE(j["strain"].get<bool>());
  EXPECT_FALSE(j["summary"]["bake"].contains("strain_mean"));
  EXPECT_NE(r.out.find("strain: not measured (no cloth rest mesh"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("mean |strain|"), std::string::npos) << r.out;
}

/// The row of the table whose label is `label`: its cells after the label.
std::vector<std::string> tableRow(const std::string& out, const std::string& label) {
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(label + "  ", 0) == 0) {
      std::istringstream cells(line.substr(label.size()));
      std::vector<std::string> row;
      for (std::string cell; cells >> cell;) {
        row.push_back(cell);
      }
      return row;
    }
  }
  return {};
}

// Issue 43: the unit square of two triangles, stretched by 20% in x on frame 1 and at rest on
// frame 2 (the truth), against a bake at rest. By hand: the two sides along x +20%, the two
// along y 0, the diagonal sqrt(1.44 + 1) / sqrt(2) - 1 = 10.45%.
TEST(EvalCommand, StrainInTheTableAndTheJson) {
  TempDir dir;
  writeTextFile(dir.file("square.obj"), "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
  const std::vector<float> rest = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  std::vector<float> truth = {0, 0, 0, 1.2f, 0, 0, 1.2f, 1, 0, 0, 1, 0};
  truth.insert(truth.end(), rest.begin(), rest.end());
  std::vector<float> bake = rest;
  bake.insert(bake.end(), rest.begin(), rest.end());
  writePc2(dir.file("truth.pc2"), 4, 1.0f, 2, truth.data());
  writePc2(dir.file("bake.pc2"), 4, 1.0f, 2, bake.data());
  const CliRun r =
      runCli(dir, {"eval", "--truth", dir.file("truth.pc2"), "--bake", dir.file("bake.pc2"),
                   "--frames", "1-2", "--driven-mesh", dir.file("square.obj"), "--per-frame",
                   "--json", dir.file("eval.json")});
  ASSERT_EQ(r.code, 0) << r.err;
  const double diagonal = std::sqrt(2.44 / 2.0) - 1.0;
  // Over both frames: 10 values, the largest (rank 10) is 0.2; 3 of 10 over 10%.
  const double mean = (0.4 + diagonal) / 10.0;
  EXPECT_NE(r.out.find("over the 5 edges of the cloth's rest mesh"), std::string::npos) << r.out;
  // (0.4 + 0.104536) / 10 = 5.045% to the table's 4 digits.
  EXPECT_EQ(tableRow(r.out, "mean |strain|"), (std::vector<std::string>{"0%", "5.045%"})) << r.out;
  EXPECT_EQ(tableRow(r.out, "strain p95"), (std::vector<std::string>{"0%", "20%"})) << r.out;
  EXPECT_EQ(tableRow(r.out, "edges > 10%"), (std::vector<std::string>{"0%", "30%"})) << r.out;

  const nlohmann::json j = readJson(dir.file("eval.json"));
  EXPECT_TRUE(j["strain"].get<bool>());
  EXPECT_EQ(j["edges"].get<int>(), 5);
  EXPECT_EQ(j["zero_length_edges"].get<int>(), 0);
  const nlohmann::json& t = j["summary"]["truth"];
  EXPECT_NEAR(t["strain_mean"].get<double>(), mean, kStrainTol);
  EXPECT_NEAR(t["strain_p95"].get<double>(), 0.2, kStrainTol);
  EXPECT_NEAR(t["strain_share_over_10pct"].get<double>(), 0.3, 1e-15);
  const nlohmann::json& first = j["frames"][0]["truth"];
  EXPECT_NEAR(first["strain_mean"].get<double>(), (0.4 + diagonal) / 5.0, kStrainTol);
  EXPECT_NEAR(first["strain_p95"].get<double>(), 0.2, kStrainTol);
  EXPECT_NEAR(first["strain_share_over_10pct"].get<double>(), 0.6, 1e-15);
  EXPECT_EQ(j["frames"][1]["truth"]["strain_mean"].get<double>(), 0.0);
  for (const nlohmann::json& frame : j["frames"]) {
    EXPECT_EQ(frame["bake"]["strain_p95"].get<double>(), 0.0);
  }
  EXPECT_EQ(j["summary"]["bake"]["strain_mean"].get<double>(), 0.0);
}

TEST(EvalCommand, ClearErrors) {
  TempDir dir;
  const std::vector<std::string> common = {
      "eval",     "--truth", sample("test.driven.pc2"), "--bake", sample("test.driven.pc2"),
      "--frames", "1-3"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = common;
    args.insert(args.end(), extra.begin(), extra.end());
    return runCli(dir, args);
  };
  expectCliError(with({"--driver", sample("test.driver.pc2")}), 2, "--driver-mesh");
  expectCliError(with({"--baseline"}), 2, "--driver");
  expectCliError(with({"--driver", sample("test.driver.pc2"), "--driver-mesh",
                       sample("driver_rest.obj"), "--baseline"}),
                 2, "--driven-mesh");
  expectCliError(with({"--driver-mesh", sample("driver_rest.obj")}), 2, "--driver");
  // The cloth's rest mesh passed as the driver's: the vertex counts differ.
  expectCliError(
      with({"--driver", sample("test.driver.pc2"), "--driver-mesh", sample("driven_rest.obj")}), 3,
      "2146 vertices");
  // The baseline's cloth mesh must be the truth's.
  expectCliError(
      with({"--driver", sample("test.driver.pc2"), "--driver-mesh", sample("driver_rest.obj"),
            "--driven-mesh", sample("driver_rest.obj"), "--baseline"}),
      3, "cloth's rest mesh");
  // The cloth's rest mesh must be the truth's, with or without the baseline (strain).
  expectCliError(with({"--driven-mesh", sample("driver_rest.obj")}), 3, "cloth's rest mesh");
  // A frame the driver does not hold.
  CliRun r = runCli(dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake",
                          sample("test.driven.pc2"), "--frames", "1-3,500", "--driver",
                          sample("test.driver.pc2"), "--driver-mesh", sample("driver_rest.obj")});
  expectCliError(r, 3, "no frame 500");
  // Truth and bake of different meshes.
  r = runCli(dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake",
                   sample("test.driver.pc2"), "--frames", "1-3"});
  expectCliError(r, 3, "vertices");
}

// ---- eval --report: the bake's coverage verdict against the truth ----

/// Bakes the sleeve's test driver into dir/<name>/ with a report; returns the report's path.
std::string bakeWithReport(const TempDir& dir, const std::string& db, const std::string& name,
                           const std::string& frames, std::vector<std::string> extra = {}) {
  fs::create_directories(dir.file(name));
  const std::string report = dir.file(name + "/report.json");
  std::vector<std::string> args = {"bake",
                                   "--db",
                                   db,
                                   "--driver",
                                   sample("test.driver.pc2"),
                                   "--frames",
                                   frames,
                                   "--device",
                                   "host",
                                   "--quiet",
                                   "--report",
                                   report,
                                   "-o",
                                   dir.file(name + "/sleeve.####.exr")};
  args.insert(args.end(), extra.begin(), extra.end());
  const CliRun r = runCli(dir, args);
  EXPECT_EQ(r.code, 0) << r.err;
  return report;
}

TEST(EvalCommand, ReportCoverageAgainstTheTruth) {
  TempDir dir;
  const std::string db = buildPoseDb(dir);
  const std::string frames = "1-25x3";  // 9 frames
  // A first bake gives the error bounds; the second flags the upper half of them (its
  // tolerance is their median), so both the enough and the flagged frames are measured.
  const nlohmann::json first = readJson(bakeWithReport(dir, db, "first", frames));
  std::vector<double> firstPredicted;
  for (const nlohmann::json& f : first["frames"]) {
    ASSERT_TRUE(f.contains("predicted_error")) << "the pose model predicts every frame";
    firstPredicted.push_back(f["error_bound"].get<double>());
  }
  ASSERT_EQ(firstPredicted.size(), 9u);
  std::vector<double> sorted = firstPredicted;
  std::sort(sorted.begin(), sorted.end());
  std::ostringstream median;
  median << std::setprecision(17) << sorted[4];
  const std::string reportPath =
      bakeWithReport(dir, db, "bake", frames, {"--coverage-tolerance", median.str()});

  const CliRun r = runCli(dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake",
                                dir.file("bake/sleeve.####.exr"), "--frames", frames, "--report",
                                reportPath, "--per-frame", "--json", dir.file("eval.json")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("coverage (" + reportPath + "): 9 frames predicted"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("predicted  flagged"), std::string::npos) << r.out;

  // The report, read here: frame -> (predicted error, flagged).
  const nlohmann::json report = readJson(reportPath);
  EXPECT_EQ(report["database"]["driven_vertices"].get<int>(), 2244);
  const double tolerance = report["coverage"]["tolerance"].get<double>();
  std::map<int, std::pair<double, bool>> predictions;
  for (const nlohmann::json& f : report["frames"]) {
    predictions[f["frame"].get<int>()] = {f["predicted_error"].get<double>(),
                                          f["coverage"]["flagged"].get<bool>()};
  }
  // The tolerance and the largest prediction are also printed in mm (the sample is in metres).
  int worstFrame = predictions.begin()->first;
  for (const auto& [frame, prediction] : predictions) {
    worstFrame = prediction.first > predictions[worstFrame].first ? frame : worstFrame;
  }
  char toleranceMm[64], worstText[96];
  std::snprintf(toleranceMm, sizeof toleranceMm, " (%.1f mm): ", tolerance * 1000.0);
  std::snprintf(worstText, sizeof worstText, ", max %.6g (%.1f mm) at frame %d\n",
                predictions[worstFrame].first, predictions[worstFrame].first * 1000.0, worstFrame);
  const std::size_t toleranceLine = r.out.find("\n  tolerance ");
  ASSERT_NE(toleranceLine, std::string::npos) << r.out;
  EXPECT_LT(r.out.find(toleranceMm, toleranceLine), r.out.find('\n', toleranceLine + 1))
      << "expected '" << toleranceMm << "' on the tolerance line of\n"
      << r.out;
  const std::size_t predictedLine = r.out.find("\n  predicted mean vertex error: mean ");
  ASSERT_NE(predictedLine, std::string::npos) << r.out;
  EXPECT_EQ(r.out.find(worstText, predictedLine),
            r.out.find('\n', predictedLine + 1) - std::strlen(worstText) + 1)
      << "expected '" << worstText << "' ending the predicted line of\n"
      << r.out;
  const nlohmann::json j = readJson(dir.file("eval.json"));
  ASSERT_TRUE(j["coverage"].is_object()) << j.dump();
  const nlohmann::json& c = j["coverage"];
  ASSERT_EQ(j["frames"].size(), 9u);
  EXPECT_EQ(c["frames"].get<int>(), 9);
  EXPECT_EQ(c["missing"].get<int>(), 0);
  EXPECT_EQ(c["unpredicted"].get<int>(), 0);
  EXPECT_EQ(c["report"].get<std::string>(), reportPath);
  EXPECT_EQ(c["tolerance"].get<double>(), tolerance);

  std::vector<double> predicted, truth;
  double enoughSum = 0.0, flaggedSum = 0.0;
  int enough = 0, flagged = 0, missed = 0;
  for (const nlohmann::json& frame : j["frames"]) {
    const int number = frame["frame"].get<int>();
    ASSERT_EQ(predictions.count(number), 1u) << number;
    const auto [error, flag] = predictions[number];
    ASSERT_TRUE(frame["coverage"].is_object()) << frame.dump();
    EXPECT_EQ(frame["coverage"]["predicted_error"].get<double>(), error) << number;
    EXPECT_EQ(frame["coverage"]["flagged"].get<bool>(), flag) << number;
    EXPECT_EQ(frame["coverage"]["true_error"].get<double>(), frame["mean"].get<double>()) << number;
    predicted.push_back(error);
    truth.push_back(frame["mean"].get<double>());
    (flag ? flaggedSum : enoughSum) += frame["mean"].get<double>();
    ++(flag ? flagged : enough);
    missed += !flag && frame["mean"].get<double>() > tolerance;
  }
  ASSERT_GT(enough, 0);
  ASSERT_GT(flagged, 0);
  EXPECT_EQ(c["enough"].get<int>(), enough);
  EXPECT_EQ(c["flagged"].get<int>(), flagged);
  EXPECT_NEAR(c["covered_fraction"].get<double>(), enough / 9.0, 1e-15);
  expectRel(c["enough_true_error"].get<double>(), enoughSum / enough, kEvalErrorRelTol,
            "enough frames' true error");
  expectRel(c["flagged_true_error"].get<double>(), flaggedSum / flagged, kEvalErrorRelTol,
            "flagged frames' true error");
  // The verdict holds when the report's level of the enough frames are truly within it.
  const double level = report["coverage"]["level"].get<double>();
  ASSERT_GT(level, 0.0) << "db build calibrates the verdict";
  EXPECT_EQ(c["level"].get<double>(), level);
  EXPECT_EQ(c["missed"].get<int>(), missed);
  EXPECT_DOUBLE_EQ(c["within_share"].get<double>(), double(enough - missed) / enough);
  EXPECT_EQ(c["verdict_holds"].get<bool>(), double(enough - missed) / enough >= level);
  EXPECT_NEAR(c["spearman"].get<double>(), referenceSpearman(predicted, truth),
              testing::kRankCorrelationTol);
  std::printf("[ measured ] sleeve %s: Spearman %.3f over 9 frames, covered %.3f\n", frames.c_str(),
              c["spearman"].get<double>(), c["covered_fraction"].get<double>());

  // Frames the report lacks are counted: the same report with its first three frames removed.
  nlohmann::json partial = report;
  partial["frames"].erase(partial["frames"].begin(), partial["frames"].begin() + 3);
  writeFileAtomically(dir.file("partial.json"), partial.dump());
  const CliRun p = runCli(dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake",
                                dir.file("bake/sleeve.####.exr"), "--frames", frames, "--report",
                                dir.file("partial.json"), "--json", dir.file("partial_eval.json")});
  ASSERT_EQ(p.code, 0) << p.err;
  const nlohmann::json pj = readJson(dir.file("partial_eval.json"));
  EXPECT_EQ(pj["coverage"]["frames"].get<int>(), 6);
  EXPECT_EQ(pj["coverage"]["missing"].get<int>(), 3);
  EXPECT_TRUE(pj["frames"][0]["coverage"].is_null());
  EXPECT_NE(p.out.find("(3 not in the report, 0 without a prediction)"), std::string::npos)
      << p.out;
}

TEST(EvalCommand, ReportErrors) {
  TempDir dir;
  const std::string db = buildPoseDb(dir);
  const std::string frames = "1-7x3";
  const std::string qp = bakeWithReport(dir, db, "qp", frames, {"--weights", "qp"});
  const std::string model = bakeWithReport(dir, db, "model", frames);
  auto eval = [&](const std::string& report) {
    return runCli(dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake",
                        dir.file("model/sleeve.####.exr"), "--frames", frames, "--report", report});
  };
  // A QP bake predicts nothing: say so, and what to do.
  CliRun r = eval(qp);
  expectCliError(r, 3, qp + ": no frame has a predicted error (its weights are 'qp')");
  EXPECT_NE(r.err.find("bake with it"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("pose model"), std::string::npos) << r.err;
  // Not JSON, not a report, not this bake's cloth, not there.
  writeFileAtomically(dir.file("text.json"), "frames: 1-7x3\n");
  expectCliError(eval(dir.file("text.json")), 3, dir.file("text.json") + ": not valid JSON");
  writeFileAtomically(dir.file("eval_like.json"), R"({"mean": 0.1, "summary": {}})");
  expectCliError(eval(dir.file("eval_like.json")), 3,
                 dir.file("eval_like.json") + ": no \"frames\" array");
  nlohmann::json other = readJson(model);
  other["database"]["driven_vertices"] = 2146;
  writeFileAtomically(dir.file("other.json"), other.dump());
  expectCliError(eval(dir.file("other.json")), 3,
                 "report is of a bake of 2146 cloth vertices, the bake '" +
                     dir.file("model/sleeve.####.exr") + "' has 2244");
  expectCliError(eval(dir.file("none.json")), 3, "none.json");
}

}  // namespace
}  // namespace drivenshape
