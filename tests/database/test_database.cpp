// SPDX-License-Identifier: Apache-2.0
// Database construction (greedy farthest-point pick, manual picks, duplicates) and the file
// format (round trip, corruption, versions).

#include <drivenshape/database.h>
#include <drivenshape/database_build.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <random>

#include <drivenshape/error.h>
#include <drivenshape/point_cache.h>

#include "hash.h"

#include "test_support.h"

namespace drivenshape {
namespace {

using testing::TempDir;

/// A little grid mesh of `n` x `n` vertices with quads, one group.
Mesh gridMesh(int n, float offset) {
  Mesh mesh;
  mesh.positions.resize(n * n, 3);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      mesh.positions.row(y * n + x) << float(x), float(y), offset;
    }
  }
  mesh.faceStart.push_back(0);
  for (int y = 0; y + 1 < n; ++y) {
    for (int x = 0; x + 1 < n; ++x) {
      for (int v : {y * n + x, y * n + x + 1, (y + 1) * n + x + 1, (y + 1) * n + x}) {
        mesh.faceVertices.push_back(v);
      }
      mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
      mesh.faceGroup.push_back(0);
    }
  }
  mesh.groupNames = {"default"};
  mesh.triangulate();
  return mesh;
}

/// Writes `frames` random deformations of `mesh` as a PC2 starting at frame 1.
std::vector<float> writeRandomCache(const std::string& path, const Mesh& mesh, int frames,
                                    std::mt19937& rng, float amplitude) {
  std::normal_distribution<float> noise(0.0f, amplitude);
  const std::size_t values = static_cast<std::size_t>(mesh.vertexCount()) * 3;
  std::vector<float> data(values * frames);
  for (int f = 0; f < frames; ++f) {
    for (std::size_t i = 0; i < values; ++i) {
      data[f * values + i] = mesh.positions.data()[i] + noise(rng);
    }
  }
  writePc2(path, mesh.vertexCount(), 1.0f, frames, data.data());
  return data;
}

double rms(const float* a, const float* b, std::size_t values) {
  double sum = 0;
  for (std::size_t i = 0; i < values; ++i) {
    sum += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
  }
  return std::sqrt(sum / (values / 3));
}

/// The greedy farthest-point order, computed independently of the library: every step
/// recomputes the min distance to the chosen set from scratch.
std::vector<int> referencePicks(const std::vector<float>& shapes, std::size_t values, int frames,
                                int count, int seed) {
  std::vector<int> chosen = {seed};
  while (static_cast<int>(chosen.size()) < count) {
    int best = -1;
    double bestDistance = -1;
    for (int c = 0; c < frames; ++c) {
      if (std::find(chosen.begin(), chosen.end(), c) != chosen.end()) {
        continue;
      }
      double nearest = std::numeric_limits<double>::infinity();
      for (int s : chosen) {
        nearest = std::min(nearest, rms(&shapes[c * values], &shapes[s * values], values));
      }
      if (nearest > bestDistance) {
        bestDistance = nearest;
        best = c;
      }
    }
    chosen.push_back(best);
  }
  return chosen;
}

TEST(Database, SeedIsTheEndOfTheOpeningHoldAtRest) {
  // A simulated reference clip: frames 1-5 hold the rest pose while the cloth drapes (the
  // driven shapes differ), then the character moves. The seed must be frame 5, the settled one.
  std::mt19937 rng(testing::testSeed());
  TempDir dir;
  const Mesh driver = gridMesh(6, 0.0f);
  const Mesh driven = gridMesh(5, 0.1f);
  const int frames = 20;
  const std::size_t values = driver.vertexCount() * 3;
  std::vector<float> driverData =
      writeRandomCache(dir.file("unused.pc2"), driver, frames, rng, 0.2f);
  for (int f = 0; f < 5; ++f) {
    std::copy_n(driver.positions.data(), values, &driverData[f * values]);
  }
  writePc2(dir.file("driver.pc2"), driver.vertexCount(), 1.0f, frames, driverData.data());
  writeRandomCache(dir.file("driven.pc2"), driven, frames, rng, 0.2f);
  const auto driverCache = openPointCache(dir.file("driver.pc2"));
  const auto drivenCache = openPointCache(dir.file("driven.pc2"));
  DatabaseBuildOptions options;
  options.count = 4;
  const Database db = buildDatabase(driver, driven, *driverCache, *drivenCache, options);
  ASSERT_GE(db.shapeCount(), 1);
  EXPECT_EQ(db.frames[0], 5);
  EXPECT_EQ(db.reasons[0], PickReason::kSeed);
}

TEST(Database, GreedyFarthestPointMatchesBruteForce) {
  std::mt19937 rng(testing::testSeed());
  TempDir dir;
  const Mesh driver = gridMesh(6, 0.0f);
  const Mesh driven = gridMesh(5, 0.1f);
  const int frames = 40;
  const std::vector<float> driverData =
      writeRandomCache(dir.file("driver.pc2"), driver, frames, rng, 0.2f);
  writeRandomCache(dir.file("driven.pc2"), driven, frames, rng, 0.2f);
  const auto driverCache = openPointCache(dir.file("driver.pc2"));
  const auto drivenCache = openPointCache(dir.file("driven.pc2"));

  DatabaseBuildOptions options;
  options.count = 12;
  const Database db = buildDatabase(driver, driven, *driverCache, *drivenCache, options);
  // The seed is the frame nearest the rest driver (random frames: no two within tolerance).
  const std::size_t values = driver.vertexCount() * 3;
  int seed = 0;
  for (int f = 1; f < frames; ++f) {
    if (rms(&driverData[f * values], driver.positions.data(), values) <
        rms(&driverData[seed * values], driver.positions.data(), values)) {
      seed = f;
    }
  }
  const std::vector<int> expected = referencePicks(driverData, values, frames, 12, seed);
  ASSERT_EQ(db.shapeCount(), 12);
  for (int i = 0; i < 12; ++i) {
    EXPECT_EQ(db.frames[i], expected[i] + 1) << "pick " << i;  // PC2 frames start at 1
  }
  EXPECT_EQ(db.reasons[0], PickReason::kSeed);
  // Shapes are copied from the caches of the picked frames.
  std::vector<float> frame(driven.vertexCount() * 3);
  drivenCache->readFrame(db.frames[5], frame.data());
  EXPECT_TRUE(std::equal(frame.begin(), frame.end(), db.drivenShapes.begin() + 5 * frame.size()));
}

TEST(Database, ManualPicksSeedAndRemovedFramesNeverAppear) {
  std::mt19937 rng(testing::testSeed());
  TempDir dir;
  const Mesh driver = gridMesh(4, 0.0f);
  const Mesh driven = gridMesh(4, 0.1f);
  writeRandomCache(dir.file("driver.pc2"), driver, 30, rng, 0.3f);
  writeRandomCache(dir.file("driven.pc2"), driven, 30, rng, 0.3f);
  const auto driverCache = openPointCache(dir.file("driver.pc2"));
  const auto drivenCache = openPointCache(dir.file("driven.pc2"));
  DatabaseBuildOptions options;
  options.count = 10;
  options.addFrames = {17, 3};
  options.removeFrames = {1, 2, 4, 5, 6};
  const Database db = buildDatabase(driver, driven, *driverCache, *drivenCache, options);
  ASSERT_EQ(db.shapeCount(), 10);
  EXPECT_EQ(db.frames[0], 17);
  EXPECT_EQ(db.frames[1], 3);
  EXPECT_EQ(db.reasons[1], PickReason::kAdded);
  for (int frame : db.frames) {
    EXPECT_TRUE(std::find(options.removeFrames.begin(), options.removeFrames.end(), frame) ==
                options.removeFrames.end())
        << "removed frame " << frame << " was picked";
  }
  options.removeFrames = {17};
  EXPECT_THROW(buildDatabase(driver, driven, *driverCache, *drivenCache, options), Error);
}

TEST(Database, NearDuplicateShapesAreRejected) {
  TempDir dir;
  const Mesh driver = gridMesh(4, 0.0f);
  const Mesh driven = gridMesh(4, 0.1f);
  // Three distinct shapes, each repeated with a tiny perturbation.
  const std::size_t values = driver.vertexCount() * 3;
  std::vector<float> data;
  for (int copy = 0; copy < 4; ++copy) {
    for (int shape = 0; shape < 3; ++shape) {
      for (std::size_t i = 0; i < values; ++i) {
        data.push_back(driver.positions.data()[i] + (i % 3 == 2 ? shape * 0.5f : 0.0f) +
                       copy * 1e-6f);
      }
    }
  }
  writePc2(dir.file("driver.pc2"), driver.vertexCount(), 1.0f, 12, data.data());
  std::vector<float> drivenData(driven.vertexCount() * 3 * 12, 0.5f);
  writePc2(dir.file("driven.pc2"), driven.vertexCount(), 1.0f, 12, drivenData.data());
  const auto driverCache = openPointCache(dir.file("driver.pc2"));
  const auto drivenCache = openPointCache(dir.file("driven.pc2"));
  DatabaseBuildOptions options;
  options.count = 8;
  const Database db = buildDatabase(driver, driven, *driverCache, *drivenCache, options);
  EXPECT_EQ(db.shapeCount(), 3) << "only three distinct shapes exist";
}

TEST(Database, FileRoundTripAndCorruption) {
  std::mt19937 rng(testing::testSeed());
  TempDir dir;
  Mesh driver = gridMesh(5, 0.0f);
  driver.groupNames = {"left", "right"};
  for (std::size_t f = 0; f < driver.faceGroup.size(); ++f) {
    driver.faceGroup[f] = int(f % 2);
  }
  const Mesh driven = gridMesh(4, 0.1f);
  writeRandomCache(dir.file("driver.pc2"), driver, 20, rng, 0.3f);
  writeRandomCache(dir.file("driven.pc2"), driven, 20, rng, 0.3f);
  const auto driverCache = openPointCache(dir.file("driver.pc2"));
  const auto drivenCache = openPointCache(dir.file("driven.pc2"));
  DatabaseBuildOptions options;
  options.count = 6;
  const Database db = buildDatabase(driver, driven, *driverCache, *drivenCache, options);
  const std::string path = dir.file("db.dsdb");
  saveDatabase(path, db);
  ASSERT_TRUE(isDatabaseFile(path));
  const Database back = loadDatabase(path);
  EXPECT_EQ(back.frames, db.frames);
  EXPECT_EQ(back.driverShapes, db.driverShapes);
  EXPECT_EQ(back.drivenShapes, db.drivenShapes);
  EXPECT_EQ(back.driverMesh.groupNames, driver.groupNames);
  EXPECT_EQ(back.driverMesh.faceGroup, driver.faceGroup);
  EXPECT_EQ(topologyHash(back.drivenMesh), topologyHash(driven));
  EXPECT_EQ(back.contentHash(), db.contentHash());

  // Flip one byte near the end (inside a shape block): the checksum must catch it.
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto expectRejected = [&](const std::string& content, const std::string& fragment) {
    const std::string bad = dir.file("bad.dsdb");
    std::ofstream(bad, std::ios::binary) << content;
    try {
      loadDatabase(bad);
      ADD_FAILURE() << "accepted a database with: " << fragment;
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kInput);
      EXPECT_NE(std::string(error.what()).find(fragment), std::string::npos) << error.what();
      EXPECT_NE(std::string(error.what()).find("bad.dsdb"), std::string::npos) << error.what();
    }
  };
  std::string flipped = bytes;
  flipped[flipped.size() - 20] ^= 0x5a;
  expectRejected(flipped, "checksum");
  expectRejected(bytes.substr(0, bytes.size() / 2), "truncated");
  std::string future = bytes;
  future[8] = 9;  // format version 9
  expectRejected(future, "format version 9");
  expectRejected("not a database at all, just text", "not a drivenshape database");
}

/// The file at `path` with int32 entry `index` of block `name` set to `value` and the block's
/// checksum in the header recomputed, so that only the reader's consistency checks can catch
/// it (the checksum is 16 hex digits: the header keeps its length and every offset holds).
std::string withBlockEntry(const std::string& path, const std::string& name, std::size_t index,
                           std::int32_t value) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::uint64_t headerLength = 0;
  std::memcpy(&headerLength, bytes.data() + 16, 8);
  const nlohmann::json header = nlohmann::json::parse(bytes.substr(24, headerLength));
  for (const nlohmann::json& block : header.at("blocks")) {
    if (block.at("name") != name) {
      continue;
    }
    const std::size_t offset = block.at("offset").get<std::size_t>();
    const std::size_t size = block.at("bytes").get<std::size_t>();
    EXPECT_LT(index * 4, size) << name;
    std::memcpy(&bytes[offset + index * 4], &value, 4);
    const std::string oldSum = block.at("fnv1a64").get<std::string>();
    const std::string newSum = hashToHex(Hasher().add(bytes.data() + offset, size).value());
    const std::size_t at = bytes.find(oldSum, 24);
    EXPECT_LT(at, 24 + headerLength);
    bytes.replace(at, oldSum.size(), newSum);
    // The whole file's checksum too: its 16 digits, read as '0's, are part of what it sums.
    const std::size_t key = bytes.find("\"file_fnv1a64\": \"", 24);
    EXPECT_LT(key, 24 + headerLength);
    const std::size_t digits = key + std::string("\"file_fnv1a64\": \"").size();
    bytes.replace(digits, 16, std::string(16, '0'));
    bytes.replace(digits, 16, hashToHex(Hasher().add(bytes.data(), bytes.size()).value()));
    return bytes;
  }
  ADD_FAILURE() << "no block " << name;
  return bytes;
}

// Regression (fuzzing): a face offset past the face-vertex block, with a valid checksum,
// overflowed the heap in Mesh::triangulate; a huge one overflowed the triangle count.
TEST(Database, CraftedFaceOffsetsWithValidChecksumsAreRefused) {
  std::mt19937 rng(testing::testSeed());
  TempDir dir;
  const Mesh driver = gridMesh(5, 0.0f);
  const Mesh driven = gridMesh(4, 0.1f);
  writeRandomCache(dir.file("driver.pc2"), driver, 12, rng, 0.3f);
  writeRandomCache(dir.file("driven.pc2"), driven, 12, rng, 0.3f);
  DatabaseBuildOptions options;
  options.count = 4;
  const std::string path = dir.file("db.dsdb");
  saveDatabase(path, buildDatabase(driver, driven, *openPointCache(dir.file("driver.pc2")),
                                   *openPointCache(dir.file("driven.pc2")), options));
  const int corners = static_cast<int>(driven.faceVertices.size());
  struct Case {
    std::string block;
    std::size_t index;
    std::int32_t value;
  };
  const std::vector<Case> cases = {
      {"driven_face_start", 1, corners + 4000},                          // past the corners
      {"driven_face_start", 1, 2147483000},                              // triangle count overflow
      {"driven_face_start", 2, 1},                                       // decreasing
      {"driven_face_start", 0, -8},                                      // negative start
      {"driver_face_vertices", 3, 1 << 30},                              // vertex id out of range
      {"driven_face_group", 0, 7},                                       // group id out of range
      {"driven_face_start", driven.faceStart.size() - 1, corners - 1}};  // short of the end
  for (const Case& c : cases) {
    const std::string bad = dir.file("bad.dsdb");
    std::ofstream(bad, std::ios::binary) << withBlockEntry(path, c.block, c.index, c.value);
    testing::expectThrows([&] { loadDatabase(bad); }, ErrorCode::kInput, "bad.dsdb");
  }
  // The untouched file still loads (the crafting itself is sound).
  std::ofstream(dir.file("same.dsdb"), std::ios::binary)
      << withBlockEntry(path, "driven_face_start", 1, driven.faceStart[1]);
  EXPECT_EQ(topologyHash(loadDatabase(dir.file("same.dsdb")).drivenMesh), topologyHash(driven));
}

// Regression: a folder given as the database was an internal error (basic_filebuf::underflow).
TEST(Database, FolderIsAnInputError) {
  TempDir dir;
  testing::expectThrows([&] { loadDatabase(dir.path()); }, ErrorCode::kInput, "is a folder");
}

TEST(Database, MismatchedCachesAreRefused) {
  std::mt19937 rng(testing::testSeed());
  TempDir dir;
  const Mesh driver = gridMesh(4, 0.0f);
  const Mesh driven = gridMesh(4, 0.1f);
  const Mesh other = gridMesh(3, 0.0f);
  writeRandomCache(dir.file("driver.pc2"), driver, 5, rng, 0.1f);
  writeRandomCache(dir.file("short.pc2"), driven, 3, rng, 0.1f);
  writeRandomCache(dir.file("other.pc2"), other, 5, rng, 0.1f);
  const auto driverCache = openPointCache(dir.file("driver.pc2"));
  const auto shortCache = openPointCache(dir.file("short.pc2"));
  const auto otherCache = openPointCache(dir.file("other.pc2"));
  DatabaseBuildOptions options;
  options.count = 3;
  // Driven cache lacks frames 4-5 that the driver has.
  try {
    buildDatabase(driver, driven, *driverCache, *shortCache, options);
    ADD_FAILURE() << "accepted a driven cache with missing frames";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInput);
    EXPECT_NE(std::string(error.what()).find("short.pc2"), std::string::npos) << error.what();
  }
  // Driver cache for another mesh.
  try {
    buildDatabase(driver, driven, *otherCache, *shortCache, options);
    ADD_FAILURE() << "accepted a driver cache of another mesh";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInput);
    EXPECT_NE(std::string(error.what()).find("other.pc2"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace drivenshape
