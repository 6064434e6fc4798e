// SPDX-License-Identifier: Apache-2.0
// Binding masks: the file format, its errors, and masked closest-triangle search on crossed
// "legs" (each trouser leg bound to its own leg).

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include <drivenshape/error.h>

#include "closest.h"

#include "correction_fixture.h"
#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// Two cubes (n x n quads a side) centred at x = -offset and x = +offset, in groups
/// `left` and `right`; the mesh also names an empty group "unused".
Mesh twoCubes(int n, float halfSize, float offset, const std::string& left,
              const std::string& right) {
  const Mesh cube = subdividedCube(n);
  const int vertexCount = cube.vertexCount();
  std::vector<float> xyz;
  std::vector<std::vector<int>> faces;
  for (int side = 0; side < 2; ++side) {
    for (int v = 0; v < vertexCount; ++v) {
      xyz.push_back(cube.positions(v, 0) * halfSize + (side == 0 ? -offset : offset));
      xyz.push_back(cube.positions(v, 1) * halfSize);
      xyz.push_back(cube.positions(v, 2) * halfSize);
    }
    for (int f = 0; f < cube.faceCount(); ++f) {
      std::vector<int> face;
      for (int k = cube.faceStart[static_cast<std::size_t>(f)];
           k < cube.faceStart[static_cast<std::size_t>(f) + 1]; ++k) {
        face.push_back(cube.faceVertices[static_cast<std::size_t>(k)] + side * vertexCount);
      }
      faces.push_back(face);
    }
  }
  Mesh mesh = makeMesh(xyz, faces);
  const int half = cube.faceCount();
  for (int f = 0; f < mesh.faceCount(); ++f) {
    mesh.faceGroup[static_cast<std::size_t>(f)] = f < half ? 0 : 1;
  }
  mesh.groupNames = {left, right, "unused"};
  return mesh;
}

struct Legs {
  Mesh driver = twoCubes(2, 1.0f, 2.0f, "left_leg", "right_leg");
  Mesh driven = twoCubes(3, 1.3f, 2.0f, "left_trouser", "right_trouser");
};

const char* kLegMask = R"({
  "version": 1,
  "comment": "each trouser leg binds to its own leg",
  "bindings": [
    {"name": "left", "driven": "left_trouser", "driver": ["left_leg"]},
    {"driven": {"groups": ["right_trouser"]}, "driver": {"groups": "right_leg"}}
  ]
})";

std::string errorOf(const std::string& json, const Legs& legs) {
  try {
    parseBindingMask(json, "mask.json", legs.driver, legs.driven);
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInput) << error.what();
    return error.what();
  }
  ADD_FAILURE() << "accepted: " << json;
  return "";
}

TEST(BindingMask, AllBindsEveryVertexToEveryTriangle) {
  const BindingMask mask = BindingMask::all(5);
  EXPECT_EQ(mask.drivenVertexCount(), 5);
  EXPECT_EQ(mask.classCount(), 0);
  EXPECT_TRUE(mask.isAll());
  EXPECT_TRUE(mask.allows(4, 123));
}

TEST(BindingMask, GroupNamesMapTrouserLegsToLegs) {
  const Legs legs;
  const BindingMask mask = parseBindingMask(kLegMask, "mask.json", legs.driver, legs.driven);
  ASSERT_EQ(mask.drivenVertexCount(), legs.driven.vertexCount());
  ASSERT_EQ(mask.classCount(), 2);
  const int half = legs.driver.triangleCount() / 2;
  for (int v = 0; v < legs.driven.vertexCount(); ++v) {
    const bool left = v < legs.driven.vertexCount() / 2;
    EXPECT_EQ(mask.vertexClass(v), left ? 0 : 1);
    EXPECT_EQ(mask.allows(v, 0), left);
    EXPECT_EQ(mask.allows(v, half), !left);
  }
  EXPECT_EQ(static_cast<int>(mask.classTriangles(0).size()), half);
}

TEST(BindingMask, IndexListsRangesSharedClassesAndUnnamedVertices) {
  const Legs legs;
  const BindingMask mask = parseBindingMask(R"({"bindings": [
      {"driven": {"vertices": [0, 1, "5-9"]}, "driver": {"faces": [0, "2-3"]}},
      {"driven": {"vertices": ["20-21"]}, "driver": {"faces": ["2-3", 0]}},
      {"driven": {"vertices": [30]}, "driver": {"groups": ["right_leg"], "faces": [1]}}]})",
                                            "inline", legs.driver, legs.driven);
  EXPECT_EQ(mask.classCount(), 2);  // entries 0 and 1 share their driver set
  for (int v : {0, 1, 5, 7, 9, 20, 21}) {
    EXPECT_EQ(mask.vertexClass(v), 0) << v;
  }
  EXPECT_EQ(mask.vertexClass(30), 1);
  for (int v : {2, 4, 10, 19, 22, 31}) {
    EXPECT_EQ(mask.vertexClass(v), -1) << v;
  }
  // Faces 0, 2, 3 are quads: two fan triangles each.
  EXPECT_EQ(mask.classTriangles(0), (std::vector<int>{0, 1, 4, 5, 6, 7}));
  EXPECT_FALSE(mask.isAll());
}

TEST(BindingMask, ReadsAFile) {
  const Legs legs;
  TempDir dir;
  {
    std::ofstream file(dir.file("legs.json"));
    file << kLegMask;
  }
  const BindingMask mask = readBindingMask(dir.file("legs.json"), legs.driver, legs.driven);
  EXPECT_EQ(mask.classCount(), 2);
  expectThrows([&] { readBindingMask(dir.file("missing.json"), legs.driver, legs.driven); },
               ErrorCode::kInput, "missing.json");
}

TEST(BindingMask, ErrorsNameTheFileTheEntryAndTheProblem) {
  const Legs legs;
  auto contains = [](const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
  };
  std::string message =
      errorOf(R"({"bindings": [{"driven": "left_trouser", "driver": "left_arm"}]})", legs);
  EXPECT_TRUE(contains(message, "mask.json") && contains(message, "bindings[0]") &&
              contains(message, "\"left_arm\"") &&
              contains(message, "\"left_leg\", \"right_leg\", \"unused\""))
      << message;
  message = errorOf(R"({"bindings": [{"driven": "shirt", "driver": "left_leg"}]})", legs);
  EXPECT_TRUE(contains(message, "\"shirt\"") && contains(message, "\"left_trouser\"")) << message;
  message = errorOf(
      R"({"bindings": [{}, {"name": "x", "driven": "left_trouser", "driver": "unused"}]})", legs);
  EXPECT_TRUE(contains(message, "bindings[0]")) << message;
  message = errorOf(
      R"({"bindings": [{"name": "x", "driven": "left_trouser", "driver": "unused"}]})", legs);
  EXPECT_TRUE(contains(message, "bindings[0] (\"x\")") && contains(message, "no faces")) << message;
  message = errorOf(R"({"bindings": [{"driven": {"vertices": []}, "driver": "left_leg"}]})", legs);
  EXPECT_TRUE(contains(message, "empty")) << message;
  message = errorOf(R"({"bindings": [{"driven": [], "driver": "left_leg"}]})", legs);
  EXPECT_TRUE(contains(message, "empty")) << message;
  message = errorOf(
      R"({"bindings": [{"driven": {"vertices": [3, 100000]}, "driver": "left_leg"}]})", legs);
  EXPECT_TRUE(contains(message, "100000") && contains(message, "out of range")) << message;
  message = errorOf(
      R"({"bindings": [{"driven": {"vertices": [0]}, "driver": {"faces": ["5-100000"]}}]})", legs);
  EXPECT_TRUE(contains(message, "100000") && contains(message, "out of range")) << message;
  message =
      errorOf(R"({"bindings": [{"driven": {"vertices": ["9-5"]}, "driver": "left_leg"}]})", legs);
  EXPECT_TRUE(contains(message, "\"9-5\"")) << message;
  message = errorOf(R"({"bindings": [
      {"driven": "left_trouser", "driver": "left_leg"},
      {"driven": {"vertices": [3]}, "driver": "right_leg"}]})",
                    legs);
  EXPECT_TRUE(contains(message, "bindings[1]") && contains(message, "vertex 3") &&
              contains(message, "bindings[0]"))
      << message;
  message = errorOf(R"({"bindings": [{"driven": "left_trouser", "driver": "left_leg",)", legs);
  EXPECT_TRUE(contains(message, "not valid JSON")) << message;
  message = errorOf(R"({"bindings": [{"drivn": "left_trouser", "driver": "left_leg"}]})", legs);
  EXPECT_TRUE(contains(message, "unknown key \"drivn\"")) << message;
  message = errorOf(R"({"version": 2, "bindings": []})", legs);
  EXPECT_TRUE(contains(message, "version")) << message;
  message = errorOf(R"([1, 2])", legs);
  EXPECT_TRUE(contains(message, "bindings")) << message;
}

// Regression (fuzzing): a number beyond double (1e999), bytes that are not UTF-8 and a number
// too large for an index escaped as internal JSON errors (exit 1) instead of input errors.
TEST(BindingMask, HostileJsonIsAnInputError) {
  const Legs legs;
  for (
      const std::string& text :
      {std::string(R"({"version": 1e999, "bindings": []})"),
       std::string(R"({"bindings": [{"driven": {"vertices": [1e999]}, "driver": "left_leg"}]})"),
       std::string("{\"bindings\": [{\"name\": \"\xff\xfe\", \"driven\": \"left_trouser\", "
                   "\"driver\": \"left_leg\"}]}"),
       std::string(
           R"({"bindings": [{"driven": {"vertices": [99999999999999999999]}, "driver": "left_leg"}]})"),
       std::string(
           R"({"bindings": [{"driven": {"vertices": [-1e300]}, "driver": "left_leg"}]})")}) {
    const std::string message = errorOf(text, legs);  // fails the test unless Error(kInput)
    EXPECT_NE(message.find("mask.json"), std::string::npos) << message;
  }
}

TEST_F(CorrectionClTest, CrossedLegsBindOnlyToTheirOwnLeg) {
  const Legs legs;
  const BindingMask mask = parseBindingMask(kLegMask, "mask.json", legs.driver, legs.driven);
  // Cross the legs: the left trouser moves over to x = +1, nearer the right leg (x = +2)
  // than its own (x = -2); the right trouser moves to x = -1.
  const int vd = legs.driven.vertexCount();
  std::vector<float> points(legs.driven.positions.data(), legs.driven.positions.data() + 3 * vd);
  for (int v = 0; v < vd; ++v) {
    points[3 * static_cast<std::size_t>(v)] += v < vd / 2 ? 3.0f : -3.0f;
  }
  const float* pose = legs.driver.positions.data();
  const int half = legs.driver.triangleCount() / 2;
  const std::vector<double> brute = bruteForceAll(legs.driver, 1, pose, points.data(), mask);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    std::vector<SurfaceHit> hits(static_cast<std::size_t>(vd));
    // Unmasked, many left-trouser points bind to the right leg: the test means something.
    backend->setSurface(legs.driver, BindingMask::all(vd));
    backend->closest(1, pose, points.data(), hits.data());
    int crossed = 0;
    for (int v = 0; v < vd / 2; ++v) {
      crossed += hits[static_cast<std::size_t>(v)].triangle >= half;
    }
    EXPECT_GT(crossed, vd / 8);
    // Masked: never.
    backend->setSurface(legs.driver, mask);
    backend->closest(1, pose, points.data(), hits.data());
    for (int v = 0; v < vd; ++v) {
      const bool leftTrouser = v < vd / 2;
      const bool leftLeg = hits[static_cast<std::size_t>(v)].triangle < half;
      ASSERT_EQ(leftTrouser, leftLeg) << "vertex " << v;
    }
    expectExact(legs.driver, 1, pose, points.data(), mask, hits, brute, kClosestDistanceTol);
  }
}

}  // namespace
}  // namespace drivenshape::testing
