// SPDX-License-Identifier: Apache-2.0
// Issue 43: the strain of the cloth's edges (drivenshape/evaluate.h): per edge, per frame and
// over a shot (evaluateShot), on hand-made meshes whose strains are known in closed form: a unit
// square of two triangles stretched and shrunk in x, a sheared strip, quads read from an OBJ
// (shared sides counted once), one vertex pulled off a strip (the percentile's rank); and the
// shot's percentile against a full sort of many random values.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <drivenshape/device.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluate.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

#include "strain_total.h"

#include "io_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

using Deform = std::function<Eigen::Vector3d(const Eigen::Vector3d&)>;

/// A mesh of the given positions and polygons.
Mesh polygonMesh(const std::vector<Eigen::Vector3d>& points,
                 const std::vector<std::vector<int>>& faces) {
  Mesh mesh;
  mesh.positions.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v) {
    mesh.positions.row(static_cast<Eigen::Index>(v)) = points[v].cast<float>().transpose();
  }
  mesh.faceStart.push_back(0);
  for (const std::vector<int>& face : faces) {
    mesh.faceVertices.insert(mesh.faceVertices.end(), face.begin(), face.end());
    mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
    mesh.faceGroup.push_back(0);
  }
  mesh.groupNames = {"cloth"};
  validateMesh(mesh, "test mesh");
  mesh.triangulate();
  return mesh;
}

/// The unit square (0,0) (1,0) (1,1) (0,1) as two triangles sharing the diagonal 0-2.
Mesh unitSquare() {
  return polygonMesh({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {{0, 1, 2}, {0, 2, 3}});
}

/// A strip of `cells` unit squares along x: vertex i at (i, 0), vertex cells + 1 + i at (i, 1);
/// each cell two triangles split by its diagonal from (i, 0) to (i + 1, 1).
Mesh strip(int cells) {
  std::vector<Eigen::Vector3d> points;
  for (int row = 0; row < 2; ++row) {
    for (int i = 0; i <= cells; ++i) {
      points.emplace_back(i, row, 0);
    }
  }
  const int top = cells + 1;
  std::vector<std::vector<int>> faces;
  for (int i = 0; i < cells; ++i) {
    faces.push_back({i, i + 1, top + i + 1});
    faces.push_back({i, top + i + 1, top + i});
  }
  return polygonMesh(points, faces);
}

/// The mesh's rest positions moved by `deform`, as a float V x 3 block.
std::vector<float> deformed(const Mesh& mesh, const Deform& deform) {
  std::vector<float> out;
  for (Eigen::Index v = 0; v < mesh.positions.rows(); ++v) {
    const Eigen::Vector3d p = deform(mesh.positions.row(v).transpose().cast<double>());
    out.insert(out.end(), {float(p.x()), float(p.y()), float(p.z())});
  }
  return out;
}

Eigen::Vector3d stretchX(const Eigen::Vector3d& p, double factor) {
  return {factor * p.x(), p.y(), p.z()};
}

void expectFigures(const StrainFigures& f, long long values, double mean, double p95,
                   double overShare, const std::string& what) {
  EXPECT_EQ(f.values, values) << what;
  EXPECT_NEAR(f.mean, mean, kStrainTol) << what << " mean";
  EXPECT_NEAR(f.p95, p95, kStrainTol) << what << " p95";
  EXPECT_NEAR(f.overShare, overShare, 1e-15) << what << " share over 10%";
}

// The diagonal of the unit square with x scaled by a: sqrt(a^2 + 1) / sqrt(2) - 1.
double squareDiagonal(double a) {
  return std::sqrt((a * a + 1.0) / 2.0) - 1.0;
}

TEST(Strain, UnitSquareStretchedByTwentyPercentInX) {
  const Mesh square = unitSquare();
  const std::vector<MeshEdge> edges = meshEdges(square);
  ASSERT_EQ(edges, (std::vector<MeshEdge>{{0, 1}, {0, 2}, {0, 3}, {1, 2}, {2, 3}}));
  const std::vector<float> frame = deformed(square, [](auto& p) { return stretchX(p, 1.2); });
  const std::vector<double> strains = edgeStrains(square.positions.data(), frame.data(), 4, edges);
  // Along x +20%, along y 0, the diagonal sqrt(1.44 + 1) / sqrt(2) - 1 = 0.10454.
  const double diagonal = squareDiagonal(1.2);
  EXPECT_NEAR(diagonal, 0.1045361017, 1e-9);
  const std::vector<double> expected = {0.2, diagonal, 0.0, 0.0, 0.2};
  ASSERT_EQ(strains.size(), expected.size());
  for (std::size_t e = 0; e < expected.size(); ++e) {
    EXPECT_NEAR(strains[e], expected[e], kStrainTol) << "edge " << e;
  }
  // Five values: the 95th percentile's rank is ceil(4.75) = 5, the largest; three over 10%.
  expectFigures(frameStrain(square.positions.data(), frame.data(), 4, edges), 5,
                (0.4 + diagonal) / 5.0, 0.2, 3.0 / 5.0, "stretched square");
}

TEST(Strain, ShrinkingCountsByItsMagnitude) {
  const Mesh square = unitSquare();
  const std::vector<float> frame = deformed(square, [](auto& p) { return stretchX(p, 0.8); });
  const std::vector<double> strains =
      edgeStrains(square.positions.data(), frame.data(), 4, meshEdges(square));
  EXPECT_NEAR(strains[0], -0.2, kStrainTol);
  // The diagonal shrinks by 1 - sqrt(0.82) = 9.45%: under the 10% limit.
  const double diagonal = squareDiagonal(0.8);
  EXPECT_NEAR(strains[1], diagonal, kStrainTol);
  expectFigures(frameStrain(square.positions.data(), frame.data(), 4, meshEdges(square)), 5,
                (0.4 - diagonal) / 5.0, 0.2, 2.0 / 5.0, "shrunk square");
}

TEST(Strain, ShearedStrip) {
  const Mesh mesh = strip(3);  // vertices 0-3 at y = 0, 4-7 at y = 1
  const double s = 0.5;
  const std::vector<float> frame = deformed(mesh, [&](const Eigen::Vector3d& p) {
    return Eigen::Vector3d(p.x() + s * p.y(), p.y(), p.z());
  });
  // By hand: the rows keep their unit lengths; an upright side (i,0)-(i,1) becomes
  // (i,0)-(i+0.5,1), of length sqrt(1.25); a diagonal (i,0)-(i+1,1), sqrt(2) at rest, becomes
  // (i,0)-(i+1.5,1), of length sqrt(3.25).
  const double side = std::sqrt(1.25) - 1.0;
  const double diagonal = std::sqrt(3.25) / std::sqrt(2.0) - 1.0;
  const std::vector<MeshEdge> edges = meshEdges(mesh);
  const std::vector<double> strains = edgeStrains(mesh.positions.data(), frame.data(), 8, edges);
  ASSERT_EQ(edges.size(), 13u);  // 6 in the rows, 4 upright, 3 diagonals
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const int a = edges[e][0], b = edges[e][1];
    const double expected = b - a == 1 ? 0.0 : b - a == 4 ? side : diagonal;
    EXPECT_NEAR(strains[e], expected, kStrainTol) << "edge " << a << "-" << b;
  }
  expectFigures(frameStrain(mesh.positions.data(), frame.data(), 8, edges), 13,
                (4 * side + 3 * diagonal) / 13.0, diagonal, 7.0 / 13.0, "sheared strip");
}

TEST(Strain, QuadsFromAnObjCountTheirSharedSideOnce) {
  TempDir dir;
  writeTextFile(dir.file("quads.obj"),
                "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\nf 1 2 5 4\nf 2 3 6 5\n");
  const Mesh mesh = readObj(dir.file("quads.obj"));
  const std::vector<MeshEdge> edges = meshEdges(mesh);
  // 2 sides along x in each row, 3 upright ones (the middle one shared), no diagonals.
  ASSERT_EQ(edges.size(), 7u);
  const std::vector<float> frame = deformed(mesh, [](auto& p) { return stretchX(p, 1.2); });
  expectFigures(frameStrain(mesh.positions.data(), frame.data(), 6, edges), 7, 4 * 0.2 / 7.0, 0.2,
                4.0 / 7.0, "stretched quads");
}

TEST(Strain, PercentileRankIsTheCeilingOf95Percent) {
  // ceil(0.95 n), worked by hand.
  EXPECT_EQ(strainPercentileRank(0), 0);
  EXPECT_EQ(strainPercentileRank(1), 1);
  EXPECT_EQ(strainPercentileRank(5), 5);                        // 4.75
  EXPECT_EQ(strainPercentileRank(20), 19);                      // 19 exactly
  EXPECT_EQ(strainPercentileRank(29), 28);                      // 27.55
  EXPECT_EQ(strainPercentileRank(58), 56);                      // 55.1
  EXPECT_EQ(strainPercentileRank(101), 96);                     // 95.95
  EXPECT_EQ(strainPercentileRank(4000000000LL), 3800000000LL);  // exact, no rounding
  EXPECT_EQ(strainPercentileRank(4000000001LL), 3800000001LL);  // 3800000000.95
}

/// The 7-cell strip with its top right vertex (7, 1) lifted to (7, 1.5).
std::vector<float> liftedCorner(const Mesh& mesh) {
  return deformed(mesh, [](const Eigen::Vector3d& p) {
    return p.x() == 7.0 && p.y() == 1.0 ? Eigen::Vector3d(7.0, 1.5, 0.0) : p;
  });
}

// The three edges at the lifted corner, by hand: the upright side (7,0)-(7,1) grows from 1 to
// 1.5, the top side (6,1)-(7,1) from 1 to sqrt(1.25), the diagonal (6,0)-(7,1) from sqrt(2) to
// sqrt(3.25); the other 26 of the 29 edges keep their length.
const double kLiftSide = 0.5;
const double kLiftTop = std::sqrt(1.25) - 1.0;
const double kLiftDiagonal = std::sqrt(3.25) / std::sqrt(2.0) - 1.0;

TEST(Strain, PercentileIsTheNearestRankNotTheMaximum) {
  const Mesh mesh = strip(7);
  const std::vector<MeshEdge> edges = meshEdges(mesh);
  ASSERT_EQ(edges.size(), 29u);
  // Rank ceil(0.95 x 29) = 28 of 29: the second largest value, the diagonal.
  expectFigures(frameStrain(mesh.positions.data(), liftedCorner(mesh).data(), 16, edges), 29,
                (kLiftSide + kLiftTop + kLiftDiagonal) / 29.0, kLiftDiagonal, 3.0 / 29.0,
                "lifted corner");
}

TEST(Strain, BadEdgesAreRefused) {
  const Mesh square = unitSquare();
  const float* rest = square.positions.data();
  expectThrows(
      [&] {
        edgeStrains(rest, rest, 4, {{0, 4}});
      },
      ErrorCode::kInput, "outside the 4 vertices");
  expectThrows([&] { edgeStrains(rest, rest, 4, {{-1, 2}}); }, ErrorCode::kInput, "outside");
  const std::vector<float> twice = {0, 0, 0, 0, 0, 0};  // two vertices at one place
  expectThrows(
      [&] {
        frameStrain(twice.data(), twice.data(), 2, {{0, 1}});
      },
      ErrorCode::kInput, "zero length at rest");
  expectFigures(frameStrain(rest, rest, 4, {}), 0, 0.0, 0.0, 0.0, "no edges");
}

// ---- The shot: evaluateShot's strain per frame and over every edge of every frame ----

/// Two frames (1 and 2) of the 7-cell strip as PC2 files: truth.pc2 (the lifted corner, then
/// the strip stretched by 20% in x) and bake.pc2 (the rest strip twice).
void writeStripShot(const Mesh& mesh, const TempDir& dir) {
  std::vector<float> truth = liftedCorner(mesh);
  const std::vector<float> stretched = deformed(mesh, [](auto& p) { return stretchX(p, 1.2); });
  truth.insert(truth.end(), stretched.begin(), stretched.end());
  std::vector<float> bake(mesh.positions.data(), mesh.positions.data() + mesh.positions.size());
  bake.insert(bake.end(), bake.begin(), bake.end());
  writePc2(dir.file("truth.pc2"), mesh.vertexCount(), 1.0f, 2, truth.data());
  writePc2(dir.file("bake.pc2"), mesh.vertexCount(), 1.0f, 2, bake.data());
}

TEST(Strain, ShotFigureIsOverEveryEdgeOfEveryFrame) {
  const Mesh mesh = strip(7);
  TempDir dir;
  writeStripShot(mesh, dir);
  const auto truth = openPointCache(dir.file("truth.pc2"));
  const auto bake = openPointCache(dir.file("bake.pc2"));
  ShotEvaluationInput input;
  input.truth = truth.get();
  input.bake = bake.get();
  input.drivenMesh = &mesh;
  const ShotEvaluation e = evaluateShot(input, {1, 2}, *makeHostDevice());
  ASSERT_TRUE(e.strain);
  EXPECT_EQ(e.edgeCount, 29);
  EXPECT_EQ(e.zeroLengthEdges, 0);
  // Frame 2 by hand: the 14 sides along x +20%, the 8 upright ones 0, the 7 diagonals
  // sqrt(1.44 + 1) / sqrt(2) - 1 (over 10%); rank 28 of 29 is 0.2.
  const double diagonal = squareDiagonal(1.2);
  ASSERT_EQ(e.truth.frames.size(), 2u);
  expectFigures(e.truth.frames[0].strain, 29, (kLiftSide + kLiftTop + kLiftDiagonal) / 29.0,
                kLiftDiagonal, 3.0 / 29.0, "truth frame 1");
  expectFigures(e.truth.frames[1].strain, 29, (14 * 0.2 + 7 * diagonal) / 29.0, 0.2, 21.0 / 29.0,
                "truth frame 2");
  // The shot: 58 values, rank ceil(55.1) = 56, the third largest (0.5, 0.2748, then fourteen
  // 0.2): not the frames' percentiles (0.2748 and 0.2) averaged or at their largest.
  expectFigures(e.truth.strain, 58,
                (kLiftSide + kLiftTop + kLiftDiagonal + 14 * 0.2 + 7 * diagonal) / 58.0, 0.2,
                24.0 / 58.0, "truth over the shot");
  // The bake is the rest strip: no strain anywhere.
  expectFigures(e.bake.strain, 58, 0.0, 0.0, 0.0, "bake over the shot");
  expectFigures(e.bake.frames[1].strain, 29, 0.0, 0.0, 0.0, "bake frame 2");
}

TEST(Strain, ShotLeavesOutZeroLengthEdgesAndNeedsTheClothsMesh) {
  // The unit square and a sliver face (1, 2, 4) whose vertex 4 sits on vertex 2: the edge 2-4
  // has no rest length and is left out; 1-4 is an edge like 1-2.
  const Mesh mesh = polygonMesh({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {1, 1, 0}},
                                {{0, 1, 2}, {0, 2, 3}, {1, 2, 4}});
  TempDir dir;
  const std::vector<float> frame = deformed(mesh, [](auto& p) { return stretchX(p, 1.2); });
  writePc2(dir.file("truth.pc2"), 5, 1.0f, 1, frame.data());
  const auto truth = openPointCache(dir.file("truth.pc2"));
  ShotEvaluationInput input;
  input.truth = truth.get();
  input.bake = truth.get();
  input.drivenMesh = &mesh;
  const ShotEvaluation e = evaluateShot(input, {1}, *makeHostDevice());
  EXPECT_TRUE(e.strain);
  EXPECT_EQ(e.edgeCount, 6);
  EXPECT_EQ(e.zeroLengthEdges, 1);
  // The square's five edges and 1-4 (upright, 0): 0.2 twice and the diagonal over 10%.
  expectFigures(e.bake.strain, 6, (0.4 + squareDiagonal(1.2)) / 6.0, 0.2, 3.0 / 6.0,
                "with a sliver");
  // Without the cloth's mesh: no strain; with another vertex count: refused.
  input.drivenMesh = nullptr;
  const ShotEvaluation none = evaluateShot(input, {1}, *makeHostDevice());
  EXPECT_FALSE(none.strain);
  EXPECT_EQ(none.bake.strain.values, 0);
  const Mesh square = unitSquare();
  input.drivenMesh = &square;
  input.drivenMeshName = "square.obj";
  expectThrows([&] { evaluateShot(input, {1}, *makeHostDevice()); }, ErrorCode::kInput,
               "cloth's rest mesh 'square.obj' has 4 vertices");
}

// The shot's percentile keeps only the largest values while frames are added (strain_total.h):
// against a plain sort of every value, over enough frames that it prunes many times, with ties
// and both signs.
TEST(StrainTotal, PercentileOverManyFramesEqualsTheSortedRank) {
  std::mt19937 rng(testSeed());
  std::normal_distribution<double> normal(0.0, 0.05);
  const int frames = 300, edges = 1000;
  StrainTotal total(static_cast<long long>(frames) * edges);
  std::vector<double> all;
  double sum = 0.0;
  long long over = 0;
  for (int f = 0; f < frames; ++f) {
    std::vector<double> strains(edges);
    for (double& s : strains) {
      s = std::round(normal(rng) * 2000.0) / 2000.0;  // ties: steps of 0.0005
      all.push_back(std::abs(s));
      sum += std::abs(s);
      over += std::abs(s) > 0.1 ? 1 : 0;
    }
    total.add(strains);
  }
  const StrainFigures f = total.figures();
  std::sort(all.begin(), all.end());
  // 300 000 values, a multiple of 20: ceil(0.95 n) is n - n / 20 exactly.
  const std::size_t rank = all.size() - all.size() / 20;
  EXPECT_EQ(f.values, static_cast<long long>(all.size()));
  EXPECT_EQ(f.p95, all[rank - 1]);
  EXPECT_NEAR(f.mean, sum / double(all.size()), 1e-12);
  EXPECT_EQ(f.overShare, double(over) / double(all.size()));
  EXPECT_GT(over, 0);
  StrainTotal short1(3);
  short1.add({0.1, 0.2});
  expectThrows([&] { short1.figures(); }, ErrorCode::kInternal, "not the 3 announced");
}

}  // namespace
}  // namespace drivenshape::testing
