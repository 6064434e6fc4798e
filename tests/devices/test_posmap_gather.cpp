// SPDX-License-Identifier: Apache-2.0
// Tests for the position-map gather: the host reference (src/devices/host/host_posmap.cpp)
// against independent double computations, and the OpenCL kernels (kernels/posmap.cl,
// src/devices/cl/cl_posmap.cpp) against the host reference.

#include <drivenshape/position_map.h>
#include <drivenshape/position_map_backend.h>
#include <drivenshape/position_map_tables.h>

#include "cl_backends.h"

#include <Eigen/Geometry>

#include <cmath>
#include <random>

#include "posmap_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

struct Maps {
  std::vector<float> positions;
  std::vector<float> normals;
};

Maps evaluate(PositionMapBackend& backend, const PositionMapTables& tables,
              const std::vector<float>& frames, int frameCount, bool normals) {
  Maps maps;
  maps.positions.assign(3 * tables.texelCount() * frameCount, -7.0f);
  if (normals) {
    maps.normals.assign(3 * tables.texelCount() * frameCount, -7.0f);
  }
  backend.evaluate(frameCount, frames.data(), maps.positions.data(),
                   normals ? maps.normals.data() : nullptr);
  return maps;
}

/// Area-weighted vertex normals in double: sum of (p1 - p0) x (p2 - p0) over the faces' fan
/// triangles around each vertex, normalised.
std::vector<Eigen::Vector3d> refVertexNormals(const Mesh& mesh, const float* xyz) {
  std::vector<Eigen::Vector3d> normals(mesh.vertexCount(), Eigen::Vector3d::Zero());
  const auto p = [&](int v) { return Eigen::Vector3d(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]); };
  for (int t = 0; t < mesh.triangleCount(); ++t) {
    const int a = mesh.triangles(t, 0);
    const int b = mesh.triangles(t, 1);
    const int c = mesh.triangles(t, 2);
    const Eigen::Vector3d n = (p(b) - p(a)).cross(p(c) - p(a));
    normals[a] += n;
    normals[b] += n;
    normals[c] += n;
  }
  for (auto& n : normals) {
    if (n.norm() > 0) {
      n.normalize();
    }
  }
  return normals;
}

TEST(PosmapHost, NormalsMatchIndependentAreaWeightedNormals) {
  const Sleeve sleeve = loadSleeve();
  const int width = 128;
  const int height = 96;
  const PositionMapTables tables = buildPositionMapTables(sleeve.mesh, width, height, 2);
  const std::vector<float> xyz = readSleeveFrames(sleeve, {40});
  auto host = makeHostPositionMaps();
  host->upload(tables);
  const Maps maps = evaluate(*host, tables, xyz, 1, true);

  const std::vector<Eigen::Vector3d> vertexNormals = refVertexNormals(sleeve.mesh, xyz.data());
  const std::vector<RefTriangle> tris = refTriangles(sleeve.mesh, width, height);
  double worst = 0.0;
  for (std::size_t e = 0; e < tables.activeCount(); ++e) {
    const std::size_t texel = tables.texels[e];
    const int t = tables.texelTriangles[e];
    const double b1 = tables.texelWeights[2 * e];
    const double b2 = tables.texelWeights[2 * e + 1];
    Eigen::Vector3d n = (1.0 - b1 - b2) * vertexNormals[tris[t].vertices[0]] +
                        b1 * vertexNormals[tris[t].vertices[1]] +
                        b2 * vertexNormals[tris[t].vertices[2]];
    n.normalize();
    for (int a = 0; a < 3; ++a) {
      worst = std::max(worst, std::abs(maps.normals[3 * texel + a] - n[a]));
    }
  }
  EXPECT_LE(worst, kNormalTol) << "worst normal component difference (tolerance " << kNormalTol
                               << ")";
  std::printf("[ measured ] worst |N - N_ref| component %.3g\n", worst);
  // Texels outside the islands and the padding hold 0 normals.
  for (std::size_t texel = 0; texel < tables.texelCount(); ++texel) {
    if (tables.coverage[texel] == 0.0f &&
        !std::binary_search(tables.texels.begin(), tables.texels.end(), static_cast<int>(texel))) {
      ASSERT_EQ(maps.normals[3 * texel], 0.0f);
      ASSERT_EQ(maps.positions[3 * texel + 2], 0.0f);
    }
  }
}

TEST(PosmapHost, DegenerateTrianglesGiveZeroNormalsNotNaN) {
  // All three vertices at one point: the normal is undefined and written as 0.
  const Mesh mesh = makeMesh({{1, 1, 1}, {1, 1, 1}, {1, 1, 1}}, {{0, 0}, {1, 0}, {0, 1}},
                             {{{0, 0}, {1, 1}, {2, 2}}});
  const PositionMapTables tables = buildPositionMapTables(mesh, 8, 8, 0);
  auto host = makeHostPositionMaps();
  host->upload(tables);
  const std::vector<float> xyz{1, 1, 1, 1, 1, 1, 1, 1, 1};
  const Maps maps = evaluate(*host, tables, xyz, 1, true);
  for (float n : maps.normals) {
    ASSERT_EQ(n, 0.0f);
  }
}

class PosmapCl : public OpenClTest {};

TEST_F(PosmapCl, MatchesTheHostReferenceOverAChunkOfFrames) {
  const Sleeve sleeve = loadSleeve();
  const PositionMapTables tables = buildPositionMapTables(sleeve.mesh, 160, 128, 4);
  const std::vector<int> frames{1, 9, 17, 25, 33, 48};
  const std::vector<float> xyz = readSleeveFrames(sleeve, frames);
  const int count = static_cast<int>(frames.size());

  auto host = makeHostPositionMaps();
  host->upload(tables);
  auto cl = makeClPositionMaps(context(), device(), queue());
  cl->upload(tables);
  const Maps want = evaluate(*host, tables, xyz, count, true);
  const Maps got = evaluate(*cl, tables, xyz, count, true);

  const std::size_t mapFloats = 3 * tables.texelCount();
  const std::size_t vertexFloats = 3 * static_cast<std::size_t>(tables.vertexCount);
  double worstP = 0.0;
  double worstN = 0.0;
  for (int f = 0; f < count; ++f) {
    const double diagonal =
        computeBounds(xyz.data() + f * vertexFloats, tables.vertexCount).diagonal();
    for (std::size_t i = 0; i < tables.texelCount(); ++i) {
      const std::size_t at = f * mapFloats + 3 * i;
      const Eigen::Vector3d dp(got.positions[at] - want.positions[at],
                               got.positions[at + 1] - want.positions[at + 1],
                               got.positions[at + 2] - want.positions[at + 2]);
      worstP = std::max(worstP, dp.norm() / diagonal);
      for (int a = 0; a < 3; ++a) {
        worstN = std::max(
            worstN, static_cast<double>(std::abs(got.normals[at + a] - want.normals[at + a])));
      }
    }
  }
  EXPECT_LE(worstP, kDeviceVsHostRelTol)
      << "worst |P_cl - P_host| / diagonal (tolerance " << kDeviceVsHostRelTol << ")";
  EXPECT_LE(worstN, kNormalTol) << "worst normal component difference (tolerance " << kNormalTol
                                << ")";
  std::printf("[ measured ] OpenCL vs host: P %.3g of the diagonal, N %.3g\n", worstP, worstN);

  // A later, smaller chunk without normals reuses the buffers: same values, zeros stay zeros.
  const std::vector<float> two(xyz.begin() + 2 * vertexFloats, xyz.begin() + 4 * vertexFloats);
  const Maps again = evaluate(*cl, tables, two, 2, false);
  for (std::size_t i = 0; i < 2 * mapFloats; ++i) {
    ASSERT_EQ(again.positions[i], got.positions[2 * mapFloats + i]) << "float " << i;
  }
}

TEST_F(PosmapCl, CoveredTexelsMatchAnIndependentBarycentricSearch) {
  const Sleeve sleeve = loadSleeve();
  const int width = 150;
  const int height = 170;
  const PositionMapTables tables = buildPositionMapTables(sleeve.mesh, width, height, 1);
  auto cl = makeClPositionMaps(context(), device(), queue());
  cl->upload(tables);
  const std::vector<float> xyz = readSleeveFrames(sleeve, {5});
  const Maps maps = evaluate(*cl, tables, xyz, 1, false);

  // Random covered texels (seeded, printed) against the test's own point-in-triangle search.
  const std::vector<RefTriangle> tris = refTriangles(sleeve.mesh, width, height);
  const std::vector<RefHit> ref = refCoverage(tris, width, height, 1.0);
  const double diagonal = computeBounds(xyz.data(), tables.vertexCount).diagonal();
  std::mt19937 random(testSeed());
  std::uniform_int_distribution<int> pick(0, width * height - 1);
  int checked = 0;
  double worst = 0.0;
  while (checked < 2000) {
    const std::size_t texel = static_cast<std::size_t>(pick(random));
    if (tables.coverage[texel] != 1.0f) {
      continue;
    }
    const RefHit& hit = ref[texel];
    ASSERT_GE(hit.triangle, 0) << "texel " << texel << " is covered but in no triangle";
    const Eigen::Vector3d expected = refInterpolate(tris[hit.triangle], hit.w, xyz.data());
    const Eigen::Vector3d got(maps.positions[3 * texel], maps.positions[3 * texel + 1],
                              maps.positions[3 * texel + 2]);
    worst = std::max(worst, (got - expected).norm() / diagonal);
    ++checked;
  }
  EXPECT_LE(worst, kPositionMapRelTol)
      << "worst |P - P_ref| / diagonal (tolerance " << kPositionMapRelTol << ")";
}

TEST_F(PosmapCl, MapWithoutCoveredTexelsIsAllZero) {
  // A sliver far thinner than a texel covers no centre: nothing to gather, all zeros.
  const Mesh mesh =
      makeMesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0.1f, 0.1f}, {0.9f, 0.1f}, {0.5f, 0.1001f}},
               {{{0, 0}, {1, 1}, {2, 2}}});
  const PositionMapTables tables = buildPositionMapTables(mesh, 4, 4, 0);
  ASSERT_EQ(tables.activeCount(), 0u);
  auto cl = makeClPositionMaps(context(), device(), queue());
  cl->upload(tables);
  const std::vector<float> xyz{0, 0, 0, 1, 0, 0, 0, 1, 0};
  const Maps maps = evaluate(*cl, tables, xyz, 1, true);
  for (float value : maps.positions) {
    ASSERT_EQ(value, 0.0f);
  }
}

}  // namespace
}  // namespace drivenshape::testing
