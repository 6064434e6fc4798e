// SPDX-License-Identifier: Apache-2.0
// countMeshDefects and checkDriverMesh (src/io/mesh_check.cpp) on tiny meshes whose counts are
// derived by hand in the comments, and on the bundled sample meshes.

#include <drivenshape/mesh.h>
#include <drivenshape/mesh_check.h>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// A mesh from positions and 0-based faces (any sizes), one group.
Mesh meshOf(const std::vector<Eigen::Vector3f>& points,
            const std::vector<std::vector<int>>& faces) {
  Mesh mesh;
  mesh.positions.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v) {
    mesh.positions.row(static_cast<Eigen::Index>(v)) = points[v].transpose();
  }
  mesh.faceStart.push_back(0);
  for (const std::vector<int>& face : faces) {
    mesh.faceVertices.insert(mesh.faceVertices.end(), face.begin(), face.end());
    mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
    mesh.faceGroup.push_back(0);
  }
  mesh.groupNames = {"default"};
  validateMesh(mesh, "meshOf");
  mesh.triangulate();
  return mesh;
}

const std::vector<Eigen::Vector3f> kTetraPoints = {
    {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};

/// The tetrahedron 0 1 2 3, every face outward: each of its 6 edges is traversed once each way
///   0-2: (0 2 1) 0->2, (0 3 2) 2->0     0-1: (0 2 1) 1->0, (0 1 3) 0->1
///   1-2: (0 2 1) 2->1, (1 2 3) 1->2     1-3: (0 1 3) 1->3, (1 2 3) 3->1
///   0-3: (0 1 3) 3->0, (0 3 2) 0->3     2-3: (0 3 2) 3->2, (1 2 3) 2->3
std::vector<std::vector<int>> tetraFaces() {
  return {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
}

void expectCounts(const MeshDefects& d, int degenerate, int open, int nonManifold,
                  int misoriented) {
  EXPECT_EQ(d.degenerateFaces, degenerate);
  EXPECT_EQ(d.openEdges, open);
  EXPECT_EQ(d.nonManifoldEdges, nonManifold);
  EXPECT_EQ(d.misorientedEdges, misoriented);
}

TEST(MeshCheck, ClosedTetrahedronHasNoDefects) {
  const MeshDefects d = countMeshDefects(meshOf(kTetraPoints, tetraFaces()));
  EXPECT_EQ(d.faces, 4);
  expectCounts(d, 0, 0, 0, 0);
  EXPECT_TRUE(d.trusted());
  EXPECT_TRUE(d.bindable());
  EXPECT_EQ(d.firstDegenerateFace, -1);
  EXPECT_EQ(d.firstOpenEdge.face, -1);
  EXPECT_EQ(d.describe(), "no defects");
}

TEST(MeshCheck, ClosedQuadCubeHasNoDefects) {
  const std::vector<Eigen::Vector3f> corners = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                                {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const MeshDefects d = countMeshDefects(
      meshOf(corners,
             {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}}));
  expectCounts(d, 0, 0, 0, 0);
  EXPECT_TRUE(d.trusted());
}

// Face 4 (1 2 3) flipped to (3 2 1) traverses 3->2, 2->1, 1->3: the same ways as (0 3 2), (0 2 1)
// and (0 1 3) do, so edges 2-3, 1-2 and 1-3 are misoriented. The first in face order is face 1's
// second edge, 2->1, which face 4 also traverses.
TEST(MeshCheck, TetrahedronWithOneFlippedFaceHasThreeMisorientedEdges) {
  std::vector<std::vector<int>> faces = tetraFaces();
  faces[3] = {3, 2, 1};
  const MeshDefects d = countMeshDefects(meshOf(kTetraPoints, faces));
  expectCounts(d, 0, 0, 0, 3);
  EXPECT_FALSE(d.trusted());
  EXPECT_TRUE(d.bindable());
  EXPECT_EQ(d.firstMisorientedEdge.from, 2);
  EXPECT_EQ(d.firstMisorientedEdge.to, 1);
  EXPECT_EQ(d.firstMisorientedEdge.face, 0);
  EXPECT_EQ(d.firstMisorientedEdge.otherFace, 3);
  // OBJ numbers are 1-based.
  EXPECT_NE(d.describe().find("3 misoriented edges"), std::string::npos) << d.describe();
  EXPECT_NE(d.describe().find("vertices 3-2 in faces 1 and 4"), std::string::npos) << d.describe();
}

// Without face 4 its three edges 1-2, 2-3, 1-3 are used once; face 1's 2->1 comes first.
TEST(MeshCheck, TetrahedronWithoutAFaceHasThreeOpenEdges) {
  std::vector<std::vector<int>> faces = tetraFaces();
  faces.pop_back();
  const MeshDefects d = countMeshDefects(meshOf(kTetraPoints, faces));
  expectCounts(d, 0, 3, 0, 0);
  EXPECT_EQ(d.firstOpenEdge.from, 2);
  EXPECT_EQ(d.firstOpenEdge.to, 1);
  EXPECT_EQ(d.firstOpenEdge.face, 0);
  EXPECT_NE(d.describe().find("3 open edges (used by one face; the first: vertices 3-2 of face 1)"),
            std::string::npos)
      << d.describe();
}

// A fin (0 1 4) on edge 0-1 makes it used by three faces (not judged for orientation), and its
// other edges 1-4 and 4-0 are used once.
TEST(MeshCheck, TetrahedronWithAFinHasANonManifoldEdgeAndTwoOpenOnes) {
  std::vector<std::vector<int>> faces = tetraFaces();
  faces.push_back({0, 1, 4});
  const MeshDefects d = countMeshDefects(meshOf(kTetraPoints, faces));
  expectCounts(d, 0, 2, 1, 0);
  EXPECT_EQ(d.firstNonManifoldEdge.uses, 3);
  EXPECT_EQ(d.firstNonManifoldEdge.face, 0);  // face 1 traverses it first, as 1->0
  EXPECT_EQ(d.firstNonManifoldEdge.from, 1);
  EXPECT_EQ(d.firstNonManifoldEdge.to, 0);
  EXPECT_EQ(d.firstOpenEdge.face, 4);
  EXPECT_EQ(d.firstOpenEdge.from, 1);
  EXPECT_EQ(d.firstOpenEdge.to, 4);
}

// A face that repeats a vertex is degenerate and adds no edge: (1 2 2) in place of (1 2 3)
// leaves the three edges of the missing face open.
TEST(MeshCheck, FaceWithARepeatedVertexIsDegenerateAndAddsNoEdge) {
  std::vector<std::vector<int>> faces = tetraFaces();
  faces[3] = {1, 2, 2};
  const MeshDefects d = countMeshDefects(meshOf(kTetraPoints, faces));
  expectCounts(d, 1, 3, 0, 0);
  EXPECT_EQ(d.firstDegenerateFace, 3);
  EXPECT_EQ(d.firstDegenerateCorners, (std::vector<int>{1, 2, 2}));
  EXPECT_NE(d.describe().find("face 4, vertices 2 3 3"), std::string::npos) << d.describe();
  EXPECT_TRUE(d.bindable());
}

// Distinct vertices without area (coincident or collinear corners) are degenerate faces but keep
// their edges: the tetrahedron flattened onto a line stays closed and consistent.
TEST(MeshCheck, FacesWithoutAreaAreDegenerateButKeepTheirEdges) {
  const std::vector<Eigen::Vector3f> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}};
  const MeshDefects d = countMeshDefects(meshOf(line, tetraFaces()));
  expectCounts(d, 4, 0, 0, 0);
  EXPECT_FALSE(d.bindable());
  const std::vector<Eigen::Vector3f> point(4, Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  expectCounts(countMeshDefects(meshOf(point, tetraFaces())), 4, 0, 0, 0);
}

// The area test is relative to the face's longest edge: a sliver 1e-9 high is degenerate at any
// scale, one 1e-3 high is a face.
TEST(MeshCheck, ZeroAreaIsRelativeToTheLongestEdge) {
  for (const float scale : {1e-3f, 1.0f, 1e3f}) {
    SCOPED_TRACE(scale);
    for (const float height : {1e-9f, 1e-3f}) {
      std::vector<Eigen::Vector3f> points = kTetraPoints;
      points[3] = Eigen::Vector3f(0.5f, height, 0.0f);  // face (0 1 3) lies along edge 0-1
      for (Eigen::Vector3f& p : points) {
        p *= scale;
      }
      const MeshDefects d = countMeshDefects(meshOf(points, tetraFaces()));
      EXPECT_EQ(d.degenerateFaces, height < 1e-6f ? 1 : 0);
    }
  }
}

// Polygons of more than 16 corners are checked for repeats by sorting: a 20-gon and its reversed
// twin make a closed, consistent (flat) surface; the same 20-gon listed twice in a row is
// degenerate, and the message shows its first 8 corners.
TEST(MeshCheck, LongPolygonsAreCheckedForRepeatedVertices) {
  std::vector<Eigen::Vector3f> ring;
  std::vector<int> polygon;
  for (int i = 0; i < 20; ++i) {
    const float angle = 6.2831853f * static_cast<float>(i) / 20.0f;
    ring.emplace_back(std::cos(angle), std::sin(angle), 0.0f);
    polygon.push_back(i);
  }
  const std::vector<int> reversed(polygon.rbegin(), polygon.rend());
  expectCounts(countMeshDefects(meshOf(ring, {polygon, reversed})), 0, 0, 0, 0);
  std::vector<int> twice(polygon.begin(), polygon.begin() + 10);
  twice.insert(twice.end(), polygon.begin(), polygon.begin() + 10);
  const MeshDefects d = countMeshDefects(meshOf(ring, {twice, polygon, reversed}));
  expectCounts(d, 1, 0, 0, 0);
  EXPECT_NE(d.describe().find("face 1, vertices 1 2 3 4 5 6 7 8 ... (20 corners)"),
            std::string::npos)
      << d.describe();
}

TEST(MeshCheck, MeshWithoutFacesIsNeitherTrustedNorBindable) {
  const MeshDefects d = countMeshDefects(meshOf(kTetraPoints, {}));
  EXPECT_EQ(d.faces, 0);
  EXPECT_FALSE(d.trusted());
  EXPECT_FALSE(d.bindable());
  expectThrows(
      [&] { checkDriverMesh(meshOf(kTetraPoints, {}), "empty.obj", DriverMeshUse::kBake, true); },
      ErrorCode::kInput, "empty.obj: the driver mesh has no faces");
}

TEST(MeshCheck, CheckDriverMeshRefusesOrWarns) {
  const Mesh closed = meshOf(kTetraPoints, tetraFaces());
  for (const bool allow : {false, true}) {
    EXPECT_EQ(checkDriverMesh(closed, "closed.obj", DriverMeshUse::kDatabase, allow), "");
  }
  std::vector<std::vector<int>> faces = tetraFaces();
  faces.pop_back();
  const Mesh open = meshOf(kTetraPoints, faces);
  for (const DriverMeshUse use :
       {DriverMeshUse::kDatabase, DriverMeshUse::kBake, DriverMeshUse::kEval}) {
    expectThrows([&] { checkDriverMesh(open, "open.obj", use, false); }, ErrorCode::kInput,
                 "open.obj: the driver mesh is not a closed, consistently oriented surface: 3 "
                 "open edges");
    expectThrows([&] { checkDriverMesh(open, "open.obj", use, false); }, ErrorCode::kInput,
                 "or pass --untrusted-driver");
    const std::string warning = checkDriverMesh(open, "open.obj", use, true);
    EXPECT_EQ(warning.rfind("open.obj: ", 0), 0u) << warning;
    EXPECT_NE(warning.find("3 open edges"), std::string::npos) << warning;
    EXPECT_NE(warning.find("--untrusted-driver: "), std::string::npos) << warning;
  }
  // Nothing to bind to: refused even when untrusted meshes are allowed.
  const Mesh allDegenerate = meshOf(kTetraPoints, {{0, 0, 0}, {1, 1, 2}});
  expectThrows(
      [&] { checkDriverMesh(allDegenerate, "flat.obj", DriverMeshUse::kBake, true); },
      ErrorCode::kInput,
      "flat.obj: every face of the driver mesh is degenerate: 2 degenerate faces (a repeated "
      "vertex or no area; the first: face 1, vertices 1 1 1)");
}

// The bundled sleeve is closed, manifold and consistent; its cloth is open (88 border edges).
TEST(MeshCheck, SampleDriverIsTrustedAndTheClothIsOpen) {
  const Mesh driverMesh = readObj(dataDir() + "/sleeve/driver_rest.obj");
  const MeshDefects driver = countMeshDefects(driverMesh);
  EXPECT_EQ(driver.faces, 2176);
  expectCounts(driver, 0, 0, 0, 0);
  EXPECT_TRUE(borderVertices(driverMesh).empty());
  const Mesh clothMesh = readObj(dataDir() + "/sleeve/driven_rest.obj");
  const MeshDefects cloth = countMeshDefects(clothMesh);
  expectCounts(cloth, 0, 88, 0, 0);
  // A tube: two rings, each with as many vertices as open edges.
  EXPECT_EQ(borderVertices(clothMesh).size(), 88u);
}

// borderVertices: the ends of the sides one face has, each once, sorted; counted by hand.
TEST(MeshCheck, BorderVerticesAreTheEndsOfTheOpenEdges) {
  // Closed: none.
  EXPECT_TRUE(borderVertices(meshOf(kTetraPoints, tetraFaces())).empty());
  // Without face 4 (1 2 3): its three edges are open.
  std::vector<std::vector<int>> open = tetraFaces();
  open.pop_back();
  EXPECT_EQ(borderVertices(meshOf(kTetraPoints, open)), (std::vector<int>{1, 2, 3}));
  // A fin (0 1 4): edge 0-1 has three faces (not a border), 1-4 and 4-0 one.
  std::vector<std::vector<int>> fin = tetraFaces();
  fin.push_back({0, 1, 4});
  EXPECT_EQ(borderVertices(meshOf(kTetraPoints, fin)), (std::vector<int>{0, 1, 4}));
  // A 2 x 2 grid of quads (vertices 0-8 row by row): every vertex but the centre, 4.
  std::vector<Eigen::Vector3f> grid;
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 3; ++x) {
      grid.emplace_back(static_cast<float>(x), static_cast<float>(y), 0.0f);
    }
  }
  EXPECT_EQ(borderVertices(meshOf(grid, {{0, 1, 4, 3}, {1, 2, 5, 4}, {3, 4, 7, 6}, {4, 5, 8, 7}})),
            (std::vector<int>{0, 1, 2, 3, 5, 6, 7, 8}));
}

}  // namespace
}  // namespace drivenshape::testing
