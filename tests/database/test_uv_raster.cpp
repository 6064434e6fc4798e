// SPDX-License-Identifier: Apache-2.0
// Tests for src/database/uv_raster.cpp: the UV-to-row convention, exact coverage of shared
// edges, overlapping islands, padding and the refusal of bad layouts and sizes.

#include <drivenshape/position_map.h>
#include <drivenshape/position_map_backend.h>
#include <drivenshape/position_map_sequence.h>
#include <drivenshape/position_map_tables.h>

#include <random>
#include <set>

#include <drivenshape/error.h>

#include "posmap_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// A single triangle (three vertices at distinct heights) with the given UVs.
Mesh triangleMesh(const Eigen::Vector2f& a, const Eigen::Vector2f& b, const Eigen::Vector2f& c) {
  return makeMesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {a, b, c}, {{{0, 0}, {1, 1}, {2, 2}}});
}

/// The unit UV square as an nx x ny grid of quads, interior vertices jittered by up to
/// `amount` of a cell, so that many triangles share edges and vertices at arbitrary
/// (non-texel-aligned) positions; amount 0 keeps the regular grid.
Mesh tiledSquare(int nx, int ny, std::uint32_t seed, float amount) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> jitter(-amount, amount);
  std::vector<Eigen::Vector3f> positions;
  std::vector<Eigen::Vector2f> uvs;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      float u = static_cast<float>(i) / nx;
      float v = static_cast<float>(j) / ny;
      if (i > 0 && i < nx && j > 0 && j < ny) {
        u += jitter(random) / nx;
        v += jitter(random) / ny;
      }
      positions.emplace_back(u, v, u * v);
      uvs.emplace_back(u, v);
    }
  }
  std::vector<std::vector<std::pair<int, int>>> faces;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i;
      const int b = a + 1;
      const int c = a + nx + 2;
      const int d = a + nx + 1;
      // Alternate the winding: mirrored UV triangles must rasterise the same way.
      if ((i + j) % 2 == 0) {
        faces.push_back({{a, a}, {b, b}, {c, c}, {d, d}});
      } else {
        faces.push_back({{a, a}, {d, d}, {c, c}, {b, b}});
      }
    }
  }
  return makeMesh(positions, uvs, faces);
}

bool isCovered(const PositionMapTables& tables, int x, int y) {
  return tables.coverage[static_cast<std::size_t>(y) * tables.width + x] == 1.0f;
}

std::vector<float> evaluateHost(const PositionMapTables& tables, const float* xyz) {
  auto host = makeHostPositionMaps();
  host->upload(tables);
  std::vector<float> positions(3 * tables.texelCount(), -1.0f);
  host->evaluate(1, xyz, positions.data(), nullptr);
  return positions;
}

TEST(UvRaster, TopLeftUvTriangleCoversTheLeftOfRowZero) {
  // v = 1 is the top of the image: a triangle hugging the (u, v) = (0, 1) corner must land on
  // the first rows, at their left ends, and nowhere near the bottom.
  const Mesh mesh = triangleMesh({0.0f, 1.0f}, {0.25f, 1.0f}, {0.0f, 0.75f});
  const PositionMapTables tables = buildPositionMapTables(mesh, 16, 16, 0);
  EXPECT_TRUE(isCovered(tables, 0, 0));
  EXPECT_TRUE(isCovered(tables, 2, 0));
  EXPECT_FALSE(isCovered(tables, 15, 0)) << "row 0's right end is u = 1";
  for (int y = 4; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) {
      EXPECT_FALSE(isCovered(tables, x, y)) << "texel " << x << "," << y;
    }
  }
  // Texel (0, 0) samples (u, v) = (1/32, 31/32): P = (u, v) mapped through the triangle.
  const std::vector<float> xyz{0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::vector<float> positions = evaluateHost(tables, xyz.data());
  const double u = 0.5 / 16.0;
  const double v = 1.0 - 0.5 / 16.0;
  // The triangle maps (0,1) -> (0,0,0), (0.25,1) -> (1,0,0), (0,0.75) -> (0,1,0).
  EXPECT_NEAR(positions[0], u / 0.25, 1e-6);
  EXPECT_NEAR(positions[1], (1.0 - v) / 0.25, 1e-6);
}

TEST(UvRaster, SharedEdgesCoverEveryTexelExactlyOnce) {
  // A tiling of the unit square with shared, non-axis-aligned edges: every texel centre lies
  // in exactly one triangle (or on edges the tie rule gives to one), so all texels are
  // covered and no overlap is reported, whatever the map size.
  const std::uint32_t seed = testSeed();
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{37, 23}, {64, 64}, {3, 101}}) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    const Mesh mesh = tiledSquare(7, 5, seed, 0.3f);
    const PositionMapTables tables = buildPositionMapTables(mesh, w, h, 2);
    EXPECT_EQ(tables.coveredCount, static_cast<long long>(w) * h);
    EXPECT_EQ(tables.paddedCount, 0);
    EXPECT_TRUE(tables.overlaps.empty()) << tables.overlaps.describe();
  }
  // Texel centres exactly on edges and vertices: the grid lines of a 2x2 grid on a 3x3 map run
  // through centres (and its middle vertex is one), the quad diagonals of a 4x4 grid on 8x8
  // do; an 8x8 grid on 16x16 puts grid lines between texels.
  for (const auto& [n, size] : std::vector<std::pair<int, int>>{{2, 3}, {4, 8}, {8, 16}}) {
    const Mesh mesh = tiledSquare(n, n, 0, 0.0f);
    const PositionMapTables tables = buildPositionMapTables(mesh, size, size, 0);
    EXPECT_EQ(tables.coveredCount, static_cast<long long>(size) * size);
    EXPECT_TRUE(tables.overlaps.empty()) << tables.overlaps.describe();
  }
}

TEST(UvRaster, OverlappingIslandsKeepTheLowestTriangleAndAreReported) {
  // Faces 1 and 2 (1-based) share the same UV square; face 3 is elsewhere.
  const std::vector<Eigen::Vector3f> positions{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                               {0, 0, 5}, {1, 0, 5}, {1, 1, 5}, {0, 1, 5},
                                               {9, 9, 9}, {9, 8, 9}, {8, 9, 9}};
  const std::vector<Eigen::Vector2f> uvs{{0.1f, 0.1f}, {0.4f, 0.1f}, {0.4f, 0.4f}, {0.1f, 0.4f},
                                         {0.6f, 0.6f}, {0.9f, 0.6f}, {0.6f, 0.9f}};
  const Mesh mesh = makeMesh(positions, uvs,
                             {{{0, 0}, {1, 1}, {2, 2}, {3, 3}},
                              {{4, 0}, {5, 1}, {6, 2}, {7, 3}},
                              {{8, 4}, {9, 5}, {10, 6}}});
  const PositionMapTables tables = buildPositionMapTables(mesh, 40, 40, 0);
  EXPECT_EQ(
      tables.overlaps.texels, tables.coveredCount - [&] {
        // Face 3's texels are not overlapped: count them by their triangle.
        long long own = 0;
        for (std::size_t e = 0; e < tables.texels.size(); ++e) {
          own += tables.triangleFaces[tables.texelTriangles[e]] == 2 ? 1 : 0;
        }
        return own;
      }());
  EXPECT_GT(tables.overlaps.texels, 50);
  ASSERT_FALSE(tables.overlaps.examples.empty());
  EXPECT_EQ(tables.overlaps.examples.front(), std::make_pair(0, 1));
  const std::string text = tables.overlaps.describe();
  EXPECT_NE(text.find("1/2"), std::string::npos) << text;
  EXPECT_NE(text.find(std::to_string(tables.overlaps.texels) + " texels"), std::string::npos)
      << text;
  // Counted band by band, each overlapped texel and each face pair once.
  const PositionMapTables survey = PositionMapRaster(mesh, 40, 40, 0).survey(5);
  EXPECT_EQ(survey.overlaps.texels, tables.overlaps.texels);
  EXPECT_EQ(survey.overlaps.facePairs, tables.overlaps.facePairs);
  // Face 1 (z = 0) wins every shared texel, face 2 (z = 5) none.
  for (std::size_t e = 0; e < tables.texels.size(); ++e) {
    EXPECT_NE(tables.triangleFaces[tables.texelTriangles[e]], 1) << "texel " << tables.texels[e];
  }

  std::ostringstream log;
  PositionMapOptions options;
  options.width = 40;
  options.height = 40;
  options.padding = 0;
  PositionMapWriter writer(mesh, options, makeHostPositionMaps(), "overlap.obj", &log);
  EXPECT_NE(log.str().find("warning: overlap.obj: UV islands overlap"), std::string::npos)
      << log.str();
}

TEST(UvRaster, CoveredTexelsMatchAnIndependentBarycentricSearch) {
  const Sleeve sleeve = loadSleeve();
  const int width = 192;
  const int height = 160;  // not square: rows and columns must not be swapped
  const PositionMapTables tables = buildPositionMapTables(sleeve.mesh, width, height, 0);
  ASSERT_TRUE(tables.overlaps.empty()) << tables.overlaps.describe();
  ASSERT_GT(tables.coveredCount, width * height / 4);

  const std::vector<float> xyz = readSleeveFrames(sleeve, {17});
  const std::vector<float> positions = evaluateHost(tables, xyz.data());
  const double diagonal = computeBounds(xyz.data(), sleeve.mesh.vertexCount()).diagonal();
  const std::vector<RefTriangle> tris = refTriangles(sleeve.mesh, width, height);
  const std::vector<RefHit> ref = refCoverage(tris, width, height, 1.0);

  // Coverage: centres clearly inside a triangle are covered, centres clearly outside all are
  // not (the library snaps UVs to 1/256 texel, so "clearly" is 0.01 texel).
  constexpr double kEdgeSlack = 0.01;
  double worst = 0.0;
  long long checked = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t texel = static_cast<std::size_t>(y) * width + x;
      const RefHit& hit = ref[texel];
      if (hit.margin > kEdgeSlack) {
        ASSERT_TRUE(isCovered(tables, x, y))
            << "texel " << x << "," << y << " is " << hit.margin << " texels inside a triangle";
      }
      if (!isCovered(tables, x, y)) {
        continue;
      }
      ASSERT_GT(hit.margin, -kEdgeSlack) << "texel " << x << "," << y << " is covered but "
                                         << -hit.margin << " texels outside every triangle";
      const Eigen::Vector3d expected = refInterpolate(tris[hit.triangle], hit.w, xyz.data());
      const Eigen::Vector3d got(positions[3 * texel], positions[3 * texel + 1],
                                positions[3 * texel + 2]);
      worst = std::max(worst, (got - expected).norm() / diagonal);
      ++checked;
    }
  }
  EXPECT_EQ(checked, tables.coveredCount);
  EXPECT_LE(worst, kPositionMapRelTol)
      << "worst |P - P_ref| / diagonal over " << checked << " covered texels (tolerance "
      << kPositionMapRelTol << ")";
  std::printf("[ measured ] covered texels %lld, worst |P - P_ref| / diagonal %.3g\n", checked,
              worst);
}

TEST(UvRaster, PaddedTexelsCopyTheirNearestCoveredTexel) {
  // The sleeve's islands fill 96% of the UV square; squeezed into part of it, the map also has
  // texels beyond the padding.
  Sleeve sleeve = loadSleeve();
  for (Eigen::Vector2f& uv : sleeve.mesh.uvs) {
    uv = Eigen::Vector2f(0.1f, 0.3f) + 0.6f * uv;
  }
  const int size = 128;
  const int padding = 3;
  const PositionMapTables tables = buildPositionMapTables(sleeve.mesh, size, size, padding);
  ASSERT_GT(tables.paddedCount, 0);
  const std::vector<float> xyz = readSleeveFrames(sleeve, {30});
  const std::vector<float> positions = evaluateHost(tables, xyz.data());

  // Independent search: the covered texel at the smallest chessboard distance (<= padding),
  // then the smallest Euclidean distance, then the lowest row-major index.
  long long padded = 0;
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      if (isCovered(tables, x, y)) {
        continue;
      }
      const std::size_t texel = static_cast<std::size_t>(y) * size + x;
      long long best = -1;
      std::tuple<int, int, long long> bestKey{padding + 1, 0, 0};
      for (int dy = -padding; dy <= padding; ++dy) {
        for (int dx = -padding; dx <= padding; ++dx) {
          const int nx = x + dx;
          const int ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= size || ny >= size || !isCovered(tables, nx, ny)) {
            continue;
          }
          const long long index = static_cast<long long>(ny) * size + nx;
          const std::tuple<int, int, long long> key{std::max(std::abs(dx), std::abs(dy)),
                                                    dx * dx + dy * dy, index};
          if (key < bestKey) {
            bestKey = key;
            best = index;
          }
        }
      }
      EXPECT_EQ(tables.coverage[texel], 0.0f) << "A is 0 on texel " << x << "," << y;
      for (int a = 0; a < 3; ++a) {
        const float value = positions[3 * texel + a];
        if (best < 0) {
          ASSERT_EQ(value, 0.0f) << "texel " << x << "," << y << " is beyond the padding";
        } else {
          ASSERT_LE(std::abs(value - positions[3 * static_cast<std::size_t>(best) + a]),
                    kPaddingCopyTol)
              << "padded texel " << x << "," << y << " should copy texel " << best % size << ","
              << best / size;
        }
      }
      padded += best >= 0 ? 1 : 0;
    }
  }
  EXPECT_EQ(padded, tables.paddedCount);
  EXPECT_GT(static_cast<long long>(tables.texelCount()) - tables.coveredCount - padded, 1000)
      << "texels beyond the padding must exist for this test to mean something";
}

// A map too large to hold its tables is rasterised a band of rows at a time: each band holds
// the whole map's texels of its rows (padding reaching across band edges included), whatever
// the band's height, and the survey counts the whole map.
TEST(UvRaster, BandsHoldTheWholeMapsRows) {
  Sleeve sleeve = loadSleeve();
  for (Eigen::Vector2f& uv : sleeve.mesh.uvs) {  // islands with room for the padding
    uv = Eigen::Vector2f(0.1f, 0.3f) + 0.6f * uv;
  }
  const int width = 96;
  const int height = 80;
  const int padding = 4;
  const PositionMapTables whole = buildPositionMapTables(sleeve.mesh, width, height, padding);
  ASSERT_GT(whole.paddedCount, 0);
  const PositionMapRaster raster(sleeve.mesh, width, height, padding);
  for (int bandRows : {1, 3, 7, 32, height}) {
    SCOPED_TRACE("bands of " + std::to_string(bandRows) + " rows");
    std::size_t e = 0;  // the whole map's entry of the band's next entry
    long long covered = 0;
    long long padded = 0;
    for (int firstRow = 0; firstRow < height; firstRow += bandRows) {
      const int rows = std::min(bandRows, height - firstRow);
      const PositionMapTables band = raster.band(firstRow, rows);
      ASSERT_EQ(band.width, width);
      ASSERT_EQ(band.height, rows);
      ASSERT_EQ(band.triangles, whole.triangles);
      const std::size_t offset = static_cast<std::size_t>(firstRow) * width;
      for (std::size_t texel = 0; texel < band.texelCount(); ++texel) {
        ASSERT_EQ(band.coverage[texel], whole.coverage[offset + texel]) << "texel " << texel;
      }
      for (std::size_t b = 0; b < band.activeCount(); ++b, ++e) {
        ASSERT_LT(e, whole.activeCount());
        ASSERT_EQ(static_cast<std::size_t>(band.texels[b]) + offset,
                  static_cast<std::size_t>(whole.texels[e]));
        ASSERT_EQ(band.texelTriangles[b], whole.texelTriangles[e]);
        ASSERT_EQ(band.texelWeights[2 * b], whole.texelWeights[2 * e]);
        ASSERT_EQ(band.texelWeights[2 * b + 1], whole.texelWeights[2 * e + 1]);
        const int source = band.texelSources[b];
        const std::size_t wholeSource = static_cast<std::size_t>(whole.texelSources[e]);
        if (source >= 0) {
          ASSERT_EQ(static_cast<std::size_t>(band.texels[source]) + offset,
                    static_cast<std::size_t>(whole.texels[wholeSource]));
        } else {  // a source in another band
          const int sourceRow = whole.texels[wholeSource] / width;
          ASSERT_TRUE(sourceRow < firstRow || sourceRow >= firstRow + rows);
        }
      }
      covered += band.coveredCount;
      padded += band.paddedCount;
    }
    EXPECT_EQ(e, whole.activeCount());
    EXPECT_EQ(covered, whole.coveredCount);
    EXPECT_EQ(padded, whole.paddedCount);
    const PositionMapTables survey = raster.survey(bandRows);
    EXPECT_EQ(survey.coveredCount, whole.coveredCount);
    EXPECT_EQ(survey.paddedCount, whole.paddedCount);
    EXPECT_TRUE(survey.texels.empty());
  }
}

TEST(UvRaster, TablesAreConsistent) {
  const Sleeve sleeve = loadSleeve();
  const PositionMapTables tables = buildPositionMapTables(sleeve.mesh, 100, 60, 2);
  EXPECT_EQ(tables.triangleCount(), sleeve.mesh.triangleCount());
  EXPECT_EQ(tables.activeCount(),
            static_cast<std::size_t>(tables.coveredCount + tables.paddedCount));
  for (int t = 0; t < tables.triangleCount(); ++t) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(tables.triangles[3 * t + k], sleeve.mesh.triangles(t, k));
    }
  }
  for (std::size_t e = 0; e < tables.activeCount(); ++e) {
    const int source = tables.texelSources[e];
    ASSERT_EQ(tables.coverage[tables.texels[source]], 1.0f) << "sources are covered texels";
    ASSERT_EQ(tables.texelTriangles[e], tables.texelTriangles[source]);
    if (e > 0) {
      ASSERT_LT(tables.texels[e - 1], tables.texels[e]) << "active texels ascend";
    }
  }
  // Every triangle appears once in the incidence list of each of its vertices.
  for (int v = 0; v < tables.vertexCount; ++v) {
    for (int i = tables.vertexTriangleStart[v]; i < tables.vertexTriangleStart[v + 1]; ++i) {
      const int t = tables.vertexTriangles[i];
      ASSERT_TRUE(tables.triangles[3 * t] == v || tables.triangles[3 * t + 1] == v ||
                  tables.triangles[3 * t + 2] == v);
    }
  }
}

TEST(UvRasterInput, MeshWithoutUvsIsRefused) {
  Mesh mesh = triangleMesh({0, 0}, {1, 0}, {0, 1});
  mesh.faceUvs.clear();
  mesh.uvs.clear();
  std::string message;
  EXPECT_EQ(codeOf([&] { buildPositionMapTables(mesh, 8, 8, 0, "cloth.obj"); }, message),
            ErrorCode::kInput);
  EXPECT_NE(message.find("cloth.obj"), std::string::npos) << message;
  EXPECT_NE(message.find("no UVs"), std::string::npos) << message;
}

TEST(UvRasterInput, CornerWithoutUvIsRefused) {
  Mesh mesh = triangleMesh({0, 0}, {1, 0}, {0, 1});
  mesh.faceUvs[1] = -1;
  std::string message;
  EXPECT_EQ(codeOf([&] { buildPositionMapTables(mesh, 8, 8, 0, "cloth.obj"); }, message),
            ErrorCode::kInput);
  EXPECT_NE(message.find("face 1"), std::string::npos) << message;
  EXPECT_NE(message.find("corner 2"), std::string::npos) << message;
}

TEST(UvRasterInput, UvOutsideTheUnitSquareIsRefusedNamingFaceAndUv) {
  // Documented rule: refuse (no wrap, no clamp). 0 and 1 themselves are inside.
  EXPECT_NO_THROW(buildPositionMapTables(triangleMesh({0, 0}, {1, 0}, {1, 1}), 8, 8, 0));
  for (const Eigen::Vector2f& bad : {Eigen::Vector2f(1.5f, 0.5f), Eigen::Vector2f(0.5f, -0.25f),
                                     Eigen::Vector2f(std::nanf(""), 0.5f)}) {
    const Mesh mesh =
        makeMesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}}, {{0, 0}, {1, 0}, {0, 1}, bad},
                 {{{0, 0}, {1, 1}, {2, 2}}, {{1, 1}, {3, 3}, {2, 2}}});
    std::string message;
    EXPECT_EQ(codeOf([&] { buildPositionMapTables(mesh, 8, 8, 0, "udim.obj"); }, message),
              ErrorCode::kInput);
    EXPECT_NE(message.find("udim.obj: face 2"), std::string::npos) << message;
    EXPECT_NE(message.find("vt 4"), std::string::npos) << message;
    EXPECT_NE(message.find("outside [0, 1]"), std::string::npos) << message;
  }
}

TEST(UvRasterInput, ResolutionAndPaddingOutOfRangeAreUsageErrors) {
  const Mesh mesh = triangleMesh({0, 0}, {1, 0}, {0, 1});
  std::string message;
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{
           {0, 8}, {8, 0}, {-1, 8}, {kMaxPositionMapSide + 1, 8}, {8, 1 << 20}}) {
    EXPECT_EQ(codeOf([&] { buildPositionMapTables(mesh, w, h, 0); }, message), ErrorCode::kUsage)
        << w << "x" << h;
    EXPECT_NE(message.find("--res"), std::string::npos) << message;
  }
  for (int padding : {-1, kMaxPositionMapPadding + 1}) {
    EXPECT_EQ(codeOf([&] { buildPositionMapTables(mesh, 8, 8, padding); }, message),
              ErrorCode::kUsage);
    EXPECT_NE(message.find("--padding"), std::string::npos) << message;
  }
}

TEST(UvRasterInput, ParsesResolutions) {
  EXPECT_EQ(parsePositionMapResolution("2048"), std::make_pair(2048, 2048));
  EXPECT_EQ(parsePositionMapResolution("2048x1024"), std::make_pair(2048, 1024));
  EXPECT_EQ(parsePositionMapResolution("16384X1"), std::make_pair(16384, 1));
  for (const char* bad : {"0", "0x8", "16385", "8x16385", "99999999999", "abc", "", "2048x",
                          "x2048", "-5", "20 48", "2048x1024x2", "1e3"}) {
    std::string message;
    EXPECT_EQ(codeOf([&] { parsePositionMapResolution(bad, "--posmap"); }, message),
              ErrorCode::kUsage)
        << "'" << bad << "'";
    EXPECT_NE(message.find("--posmap"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace drivenshape::testing
