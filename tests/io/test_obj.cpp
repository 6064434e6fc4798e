// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/mesh.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "io_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

// Facts about the bundled Blender 3.4 exports, counted with awk on the files themselves.
struct BlenderObjFacts {
  const char* name;
  int vertices;
  int uvs;
  int faces;
  int triangles;
  const char* object;
};
constexpr BlenderObjFacts kDriver = {"driver_rest.obj", 2146, 2343, 2176, 4288, "arm"};
constexpr BlenderObjFacts kDriven = {"driven_rest.obj", 2244, 2295, 2200, 4400, "sleeve"};

void expectBlenderFile(const BlenderObjFacts& facts) {
  SCOPED_TRACE(facts.name);
  const Mesh mesh = readObj(dataDir() + "/sleeve/" + facts.name);
  EXPECT_EQ(mesh.vertexCount(), facts.vertices);
  EXPECT_EQ(static_cast<int>(mesh.uvs.size()), facts.uvs);
  EXPECT_EQ(mesh.faceCount(), facts.faces);
  EXPECT_EQ(static_cast<int>(mesh.faceStart.size()), facts.faces + 1);
  EXPECT_EQ(mesh.triangleCount(), facts.triangles);
  EXPECT_EQ(static_cast<int>(mesh.triangleFace.size()), facts.triangles);
  ASSERT_TRUE(mesh.hasUvs());
  EXPECT_EQ(mesh.faceUvs.size(), mesh.faceVertices.size());
  ASSERT_EQ(mesh.groupNames.size(), 1u);
  EXPECT_EQ(mesh.groupNames[0], facts.object);
}

TEST(Obj, BlenderSleeveMeshesLoadWithTheirCounts) {
  expectBlenderFile(kDriver);
  expectBlenderFile(kDriven);
}

TEST(Obj, BlenderDriverKeepsFileOrderAndIndices) {
  const Mesh mesh = readObj(dataDir() + "/sleeve/driver_rest.obj");
  // First and last `v` lines and the first and last `f` lines of the file.
  EXPECT_EQ(mesh.positions(0, 0), 0.040000f);
  EXPECT_EQ(mesh.positions(0, 1), 0.051504f);
  EXPECT_EQ(mesh.positions(0, 2), 1.400000f);
  EXPECT_EQ(mesh.positions(1, 1), 0.050515f);
  EXPECT_EQ(mesh.uvs[0], Eigen::Vector2f(0.0f, 0.02f));
  // "f 1/1 2/5 34/69 33/67"
  EXPECT_EQ(std::vector<int>(mesh.faceVertices.begin(), mesh.faceVertices.begin() + 4),
            (std::vector<int>{0, 1, 33, 32}));
  EXPECT_EQ(std::vector<int>(mesh.faceUvs.begin(), mesh.faceUvs.begin() + 4),
            (std::vector<int>{0, 4, 68, 66}));
  // "f 2145/2342 2114/2280 2146/2343" is a triangle at the end.
  EXPECT_EQ(std::vector<int>(mesh.faceVertices.end() - 3, mesh.faceVertices.end()),
            (std::vector<int>{2144, 2113, 2145}));
  EXPECT_EQ(mesh.faceStart.back() - mesh.faceStart[mesh.faceStart.size() - 2], 3);
}

constexpr const char* kSmallObj =
    "# hand written: every statement kind we read or skip\n"
    "mtllib scene.mtl\n"
    "v 0 0 0\n"
    "v 1 0 0\n"
    "v 1 1 0\n"
    "v 0 1 0\n"
    "v 2.5 -0.5 1e-3\n"
    "vt 0 0\n"
    "vt 1 0\n"
    "vt 1 1\n"
    "vn 0 0 1\n"
    "f 1 2 3\n"
    "g left\n"
    "usemtl skin\n"
    "s 1\n"
    "f 1/1 2/2 3/3 4/1\n"
    "g right\n"
    "f 2//1 5//1 3//1\n"
    "o left\n"
    "f -5/-3/-1 -4/-2/-1 -1/-1/-1\n"
    "l 1 2\n"
    "f 1 2 3 4 5\r\n";

TEST(Obj, PolygonsGroupsAndNegativeIndices) {
  TempDir dir;
  const std::string path = dir.file("small.obj");
  writeTextFile(path, kSmallObj);
  const Mesh mesh = readObj(path);
  ASSERT_EQ(mesh.vertexCount(), 5);
  EXPECT_EQ(mesh.positions(4, 0), 2.5f);
  EXPECT_EQ(mesh.positions(4, 1), -0.5f);
  EXPECT_EQ(mesh.positions(4, 2), 1e-3f);
  EXPECT_EQ(mesh.uvs.size(), 3u);
  EXPECT_EQ(mesh.faceStart, (std::vector<int>{0, 3, 7, 10, 13, 18}));
  EXPECT_EQ(mesh.faceVertices,
            (std::vector<int>{0, 1, 2, 0, 1, 2, 3, 1, 4, 2, 0, 1, 4, 0, 1, 2, 3, 4}));
  // Corners without a `vt` index carry -1 once any face has UVs.
  EXPECT_EQ(mesh.faceUvs,
            (std::vector<int>{-1, -1, -1, 0, 1, 2, 0, -1, -1, -1, 0, 1, 2, -1, -1, -1, -1, -1}));
  EXPECT_EQ(mesh.groupNames, (std::vector<std::string>{"default", "left", "right"}));
  EXPECT_EQ(mesh.faceGroup, (std::vector<int>{0, 1, 2, 1, 1}));
  // Fan triangulation: the quad gives (0,1,2)(0,2,3), the pentagon (0,1,2)(0,2,3)(0,3,4).
  ASSERT_EQ(mesh.triangleCount(), 1 + 2 + 1 + 1 + 3);
  const std::vector<std::array<int, 3>> expected = {{0, 1, 2}, {0, 1, 2}, {0, 2, 3}, {1, 4, 2},
                                                    {0, 1, 4}, {0, 1, 2}, {0, 2, 3}, {0, 3, 4}};
  for (int t = 0; t < mesh.triangleCount(); ++t) {
    EXPECT_EQ(mesh.triangles(t, 0), expected[t][0]) << "triangle " << t;
    EXPECT_EQ(mesh.triangles(t, 1), expected[t][1]) << "triangle " << t;
    EXPECT_EQ(mesh.triangles(t, 2), expected[t][2]) << "triangle " << t;
  }
  EXPECT_EQ(mesh.triangleFace, (std::vector<int>{0, 1, 1, 2, 3, 4, 4, 4}));
}

TEST(Obj, FileWithoutUvsHasNone) {
  TempDir dir;
  const std::string path = dir.file("plain.obj");
  writeTextFile(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const Mesh mesh = readObj(path);
  EXPECT_FALSE(mesh.hasUvs());
  EXPECT_EQ(mesh.groupNames, (std::vector<std::string>{"default"}));
}

// Issue 43: the edges eval's strain measures. Two quads sharing a side, then a face that
// repeats a vertex (its sides add nothing new, and its side from a vertex to itself is none).
TEST(Mesh, EdgesAreThePolygonSidesOnceEach) {
  TempDir dir;
  const std::string path = dir.file("quads.obj");
  writeTextFile(path,
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
                "f 1 2 3 4\nf 2 5 6 3\nf 3 6 6\n");
  const Mesh mesh = readObj(path);
  // By hand, 0-based, smaller id first, sorted: the first quad's four sides, the second's
  // three others (1-2 is shared); not the fan diagonals 0-2 and 1-5.
  const std::vector<MeshEdge> expected = {{0, 1}, {0, 3}, {1, 2}, {1, 4}, {2, 3}, {2, 5}, {4, 5}};
  EXPECT_EQ(meshEdges(mesh), expected);
  EXPECT_TRUE(meshEdges(Mesh()).empty());
}

Error objError(const std::string& text, std::string& path, TempDir& dir) {
  path = dir.file("bad.obj");
  writeTextFile(path, text);
  return catchError([&] { readObj(path); });
}

TEST(Obj, OutOfRangeIndexNamesFileLineIndexAndCount) {
  TempDir dir;
  std::string path;
  const Error error = objError("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\nf 1 2 9\n", path, dir);
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path + ":6"));
  EXPECT_TRUE(contains(error.what(), "9"));
  EXPECT_TRUE(contains(error.what(), "4 vertices"));
}

TEST(Obj, NegativeIndexBeforeItsVertexIsAnError) {
  TempDir dir;
  std::string path;
  const Error error = objError("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n", path, dir);
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path + ":3"));
  EXPECT_TRUE(contains(error.what(), "-3"));
  EXPECT_TRUE(contains(error.what(), "2 vertices"));
}

// Regression (fuzzing): -2147483648 negated overflowed an int, and the file was accepted.
TEST(Obj, MostNegativeIndexIsAnErrorNotAnOverflow) {
  TempDir dir;
  for (const char* corner : {"-2147483648/1", "1/-2147483648", "-2147483647", "2147483648"}) {
    std::string path;
    const Error error = objError(
        std::string("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf ") + corner + " 2/1 3/1\n", path, dir);
    EXPECT_EQ(error.code(), ErrorCode::kInput) << corner;
    EXPECT_TRUE(contains(error.what(), path + ":5")) << corner;
  }
}

// Regression: a group name that is not UTF-8 made every JSON writer (database header, bake
// report) throw after the work was done. Such names are read as Latin-1.
TEST(Obj, GroupNameThatIsNotUtf8IsReadAsLatin1) {
  TempDir dir;
  const std::string path = dir.file("latin1.obj");
  writeTextFile(path,
                "v 0 0 0\nv 1 0 0\nv 0 1 0\ng caf\xe9 \xff\nf 1 2 3\ng caf\xc3\xa9\nf 3 2 1\n");
  const Mesh mesh = readObj(path);
  ASSERT_EQ(mesh.groupNames.size(), 2u);
  EXPECT_EQ(mesh.groupNames[0], "caf\xc3\xa9 \xc3\xbf");  // U+00E9, U+00FF
  EXPECT_EQ(mesh.groupNames[1], "caf\xc3\xa9");           // valid UTF-8 is kept as it is
}

TEST(Mesh, ValidateRefusesInconsistentFaceLists) {
  Mesh good;
  good.positions = Positions::Zero(4, 3);
  good.faceStart = {0, 4};
  good.faceVertices = {0, 1, 2, 3};
  good.faceGroup = {0};
  good.groupNames = {"default"};
  validateMesh(good, "good");
  const auto expectRefused = [](const Mesh& mesh, const char* what) {
    const Error error = catchError([&] { validateMesh(mesh, "crafted"); });
    EXPECT_EQ(error.code(), ErrorCode::kInput) << what;
    EXPECT_TRUE(contains(error.what(), "crafted")) << what;
  };
  Mesh bad = good;
  bad.faceStart = {0, 5};
  expectRefused(bad, "offset past the corners");
  bad = good;
  bad.faceStart = {0, 2, 4};
  bad.faceGroup = {0, 0};
  expectRefused(bad, "a two-corner face");
  bad = good;
  bad.faceVertices[2] = 4;
  expectRefused(bad, "vertex id out of range");
  bad = good;
  bad.faceVertices[2] = -1;
  expectRefused(bad, "negative vertex id");
  bad = good;
  bad.faceGroup = {1};
  expectRefused(bad, "group id out of range");
  bad = good;
  bad.faceGroup = {};
  expectRefused(bad, "missing group ids");
  bad = good;
  bad.faceUvs = {0, 0, 0, 0};
  expectRefused(bad, "uv ids without uvs");
  bad = good;
  bad.faceStart = {0, 2147483647};
  expectRefused(bad, "an offset near INT_MAX");
}

TEST(Obj, UvIndexOutOfRange) {
  TempDir dir;
  std::string path;
  const Error error = objError("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/7\n", path, dir);
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path + ":5"));
  EXPECT_TRUE(contains(error.what(), "7"));
}

TEST(Obj, MalformedNumberNamesLineAndText) {
  TempDir dir;
  std::string path;
  Error error = objError("v 0 0 0\nv 1 zero 0\n", path, dir);
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path + ":2"));
  EXPECT_TRUE(contains(error.what(), "zero"));

  error = objError("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2x 3\n", path, dir);
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path + ":4"));
  EXPECT_TRUE(contains(error.what(), "2x"));

  error = objError("v 0 0\n", path, dir);
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path + ":1"));

  error = objError("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", path, dir);
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path + ":4"));
}

TEST(Obj, FaceWithTwoVerticesIsAnError) {
  TempDir dir;
  std::string path;
  const Error error = objError("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", path, dir);
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path + ":4"));
  EXPECT_TRUE(contains(error.what(), "at least 3"));
}

TEST(Obj, FileWithoutVerticesIsAnError) {
  TempDir dir;
  std::string path;
  const Error error = objError("# nothing here\ng empty\n", path, dir);
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path));
  EXPECT_TRUE(contains(error.what(), "no vertices"));
}

TEST(Obj, MissingFileIsAnInputError) {
  TempDir dir;
  const std::string path = dir.file("missing.obj");
  const Error error = catchError([&] { readObj(path); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path));
}

void expectSameMesh(const Mesh& a, const Mesh& b) {
  ASSERT_EQ(a.vertexCount(), b.vertexCount());
  for (int v = 0; v < a.vertexCount(); ++v) {
    for (int k = 0; k < 3; ++k) {
      // Bitwise: OBJ text must carry every float exactly (kFileRoundTripTol is 0).
      ASSERT_LE(std::abs(a.positions(v, k) - b.positions(v, k)), kFileRoundTripTol)
          << "vertex " << v << " axis " << k;
    }
  }
  ASSERT_EQ(a.uvs.size(), b.uvs.size());
  for (std::size_t i = 0; i < a.uvs.size(); ++i) {
    EXPECT_EQ(a.uvs[i], b.uvs[i]) << "uv " << i;
  }
  EXPECT_EQ(a.faceStart, b.faceStart);
  EXPECT_EQ(a.faceVertices, b.faceVertices);
  EXPECT_EQ(a.faceUvs, b.faceUvs);
  EXPECT_EQ(a.faceGroup, b.faceGroup);
  EXPECT_EQ(a.groupNames, b.groupNames);
}

TEST(Obj, WriteThenReadIsExact) {
  TempDir dir;
  const std::string source = dir.file("small.obj");
  writeTextFile(source, kSmallObj);
  Mesh mesh = readObj(source);
  // Positions that need all 9 significant digits.
  std::mt19937 random(testSeed());
  std::uniform_real_distribution<float> coordinate(-100.0f, 100.0f);
  for (int v = 0; v < mesh.vertexCount(); ++v) {
    for (int k = 0; k < 3; ++k) {
      mesh.positions(v, k) = coordinate(random) * 1.0e-3f;
    }
  }
  mesh.uvs[1] = Eigen::Vector2f(0.1f, 1.0f / 3.0f);
  const std::string copy = dir.file("copy.obj");
  writeObj(copy, mesh);
  expectSameMesh(mesh, readObj(copy));
  EXPECT_EQ(listFolder(dir.path()), (std::vector<std::string>{"copy.obj", "small.obj"}));

  const Mesh blender = readObj(dataDir() + "/sleeve/driven_rest.obj");
  writeObj(copy, blender);
  expectSameMesh(blender, readObj(copy));
}

TEST(Obj, WriteIntoMissingFolderIsAnOutputError) {
  TempDir dir;
  const Mesh mesh = readObj(dataDir() + "/sleeve/driver_rest.obj");
  const Error error = catchError([&] { writeObj(dir.file("no/such/folder/mesh.obj"), mesh); });
  EXPECT_EQ(error.code(), ErrorCode::kOutput);
}

/// A W x H grid of quads with UVs, written by hand (not by writeObj).
std::string gridObj(int width, int height) {
  std::string text;
  char line[128];
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      std::snprintf(line, sizeof(line), "v %.6f %.6f %.6f\n", x * 0.01, y * 0.01, 0.001 * (x % 7));
      text += line;
    }
  }
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      std::snprintf(line, sizeof(line), "vt %.6f %.6f\n", x / double(width), y / double(height));
      text += line;
    }
  }
  for (int y = 0; y + 1 < height; ++y) {
    for (int x = 0; x + 1 < width; ++x) {
      const int a = y * width + x + 1;
      std::snprintf(line, sizeof(line), "f %d/%d %d/%d %d/%d %d/%d\n", a, a, a + 1, a + 1,
                    a + width + 1, a + width + 1, a + width, a + width);
      text += line;
    }
  }
  return text;
}

TEST(Obj, ReadsA200kVertexMeshQuickly) {
  TempDir dir;
  const std::string path = dir.file("grid.obj");
  constexpr int kWidth = 500;
  constexpr int kHeight = 400;
  writeTextFile(path, gridObj(kWidth, kHeight));
  const auto start = std::chrono::steady_clock::now();
  const Mesh mesh = readObj(path);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("[ timing   ] readObj of %d vertices: %.3f s\n", mesh.vertexCount(), seconds);
  EXPECT_EQ(mesh.vertexCount(), kWidth * kHeight);
  EXPECT_EQ(mesh.faceCount(), (kWidth - 1) * (kHeight - 1));
  EXPECT_EQ(mesh.triangleCount(), 2 * (kWidth - 1) * (kHeight - 1));
  EXPECT_EQ(mesh.positions(kWidth * kHeight - 1, 0), 4.99f);
  // Generous: a stream-per-token reader takes several times longer than this.
  EXPECT_LT(seconds, 2.0);
}

TEST(Mesh, TopologyHashSeesFacesNotPositions) {
  const Mesh base = readObj(dataDir() + "/sleeve/driver_rest.obj");
  Mesh moved = base;
  moved.positions.array() += 1.0f;
  moved.uvs.clear();
  moved.faceUvs.clear();
  EXPECT_EQ(topologyHash(base), topologyHash(moved));

  Mesh rewired = base;
  std::swap(rewired.faceVertices[0], rewired.faceVertices[1]);
  EXPECT_NE(topologyHash(base), topologyHash(rewired));

  Mesh split = base;  // same corner list, different polygon sizes
  split.faceStart[1] += 1;
  EXPECT_NE(topologyHash(base), topologyHash(split));

  Mesh extraVertex = base;
  extraVertex.positions.conservativeResize(base.vertexCount() + 1, 3);
  EXPECT_NE(topologyHash(base), topologyHash(extraVertex));

  EXPECT_NE(topologyHash(base), topologyHash(base.vertexCount()));
  EXPECT_NE(topologyHash(2146), topologyHash(2147));
  EXPECT_EQ(topologyHash(2146), topologyHash(2146));
  EXPECT_NE(topologyHash(base), topologyHash(readObj(dataDir() + "/sleeve/driven_rest.obj")));
}

TEST(Mesh, TriangulateBuildsFans) {
  Mesh mesh;
  mesh.positions.resize(6, 3);
  mesh.positions.setZero();
  mesh.faceStart = {0, 6, 9};
  mesh.faceVertices = {5, 4, 3, 2, 1, 0, 0, 2, 4};
  mesh.faceGroup = {0, 0};
  mesh.groupNames = {"default"};
  mesh.triangulate();
  ASSERT_EQ(mesh.triangleCount(), 5);
  const int expected[5][3] = {{5, 4, 3}, {5, 3, 2}, {5, 2, 1}, {5, 1, 0}, {0, 2, 4}};
  for (int t = 0; t < 5; ++t) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(mesh.triangles(t, k), expected[t][k]) << "triangle " << t;
    }
  }
  EXPECT_EQ(mesh.triangleFace, (std::vector<int>{0, 0, 0, 0, 1}));
}

TEST(Mesh, ComputeBounds) {
  const float xyz[] = {1.0f, -2.0f, 3.0f, -4.0f, 5.0f, 0.5f, 0.0f, 0.0f, 9.0f};
  const Bounds bounds = computeBounds(xyz, 3);
  EXPECT_EQ(bounds.min, Eigen::Vector3f(-4.0f, -2.0f, 0.5f));
  EXPECT_EQ(bounds.max, Eigen::Vector3f(1.0f, 5.0f, 9.0f));
  EXPECT_FLOAT_EQ(bounds.diagonal(), std::sqrt(25.0f + 49.0f + 8.5f * 8.5f));
  const Bounds one = computeBounds(xyz + 3, 1);
  EXPECT_EQ(one.min, one.max);
}

}  // namespace
}  // namespace drivenshape::testing
