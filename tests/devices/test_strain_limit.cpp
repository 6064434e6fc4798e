// SPDX-License-Identifier: Apache-2.0
// The strain limit's backends (src/devices/strain_limit.h: the tables, the host reference
// src/devices/host/host_strain_limit.cpp and the OpenCL kernel kernels/strain_limit.cl with
// src/devices/cl/cl_strain_limit.cpp): a stretched strip comes back into the band, edges inside
// it are left alone, fixed vertices stay, vertices keep in front of their skin planes, the
// Chebyshev acceleration gets there sooner, threads and chunks change nothing, and OpenCL agrees
// with the host on the sleeve sample, with planes and without.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <drivenshape/device.h>
#include <drivenshape/device_cl.h>
#include <drivenshape/error.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

#include "device_array.h"
#include "strain_limit.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using testing::kStrainLimitDeviceVsHostRelTol;
using testing::OpenClTest;

/// A strip of `columns` x 1 unit quads in the xy plane (vertex (i, j) is i + j (columns + 1)):
/// 3 columns + 1 edges, `columns` + 1 of them across.
Mesh strip(int columns) {
  Mesh mesh;
  const int n = columns + 1;
  mesh.positions.resize(2 * n, 3);
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < n; ++i) {
      mesh.positions.row(i + j * n) << float(i), float(j), 0.0f;
    }
  }
  mesh.faceStart.push_back(0);
  for (int i = 0; i < columns; ++i) {
    for (const int v : {i, i + 1, i + 1 + n, i + n}) {
      mesh.faceVertices.push_back(v);
    }
    mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
    mesh.faceGroup.push_back(0);
  }
  mesh.groupNames = {"strip"};
  mesh.triangulate();
  return mesh;
}

/// The rest positions of `mesh` as one frame, x scaled by `stretch` (y, z kept).
std::vector<float> stretched(const Mesh& mesh, float stretch) {
  std::vector<float> frame(mesh.positions.data(), mesh.positions.data() + mesh.positions.size());
  for (std::size_t i = 0; i < frame.size(); i += 3) {
    frame[i] *= stretch;
  }
  return frame;
}

/// The largest |strain| of `frame` over the edges of `mesh` (rest: its positions).
double largestStrain(const Mesh& mesh, const float* frame) {
  double largest = 0.0;
  for (const MeshEdge& e : meshEdges(mesh)) {
    double rest = 0.0;
    double now = 0.0;
    for (int a = 0; a < 3; ++a) {
      const double r = double(mesh.positions(e[1], a)) - mesh.positions(e[0], a);
      const double d = double(frame[3 * e[1] + a]) - frame[3 * e[0] + a];
      rest += r * r;
      now += d * d;
    }
    largest = std::max(largest, std::abs(std::sqrt(now / rest) - 1.0));
  }
  return largest;
}

/// The largest per-vertex distance between two blocks of frames.
double largestDistance(const std::vector<float>& a, const std::vector<float>& b) {
  double largest = 0.0;
  for (std::size_t i = 0; i < a.size(); i += 3) {
    const double dx = double(a[i]) - b[i];
    const double dy = double(a[i + 1]) - b[i + 1];
    const double dz = double(a[i + 2]) - b[i + 2];
    largest = std::max(largest, std::sqrt(dx * dx + dy * dy + dz * dz));
  }
  return largest;
}

std::vector<float> limited(StrainLimitBackend& backend, const StrainLimitTables& tables,
                           std::vector<float> frames, const std::vector<float>& planes = {}) {
  backend.upload(tables);
  backend.limit(static_cast<int>(frames.size() / (3 * std::size_t(tables.vertexCount))),
                frames.data(), planes.empty() ? nullptr : planes.data(), nullptr, 0.0f);
  return frames;
}

/// Planes for `frames` (F x 3V) that hold every `every`-th vertex at or above `lift` over the
/// height it starts at (m = +z, c = z + lift); the others get none.
std::vector<float> floorPlanes(const std::vector<float>& frames, int every, float lift) {
  std::vector<float> planes(frames.size() / 3 * 4, 0.0f);
  for (std::size_t v = 0; v < frames.size() / 3; v += static_cast<std::size_t>(every)) {
    planes[4 * v + 2] = 1.0f;
    planes[4 * v + 3] = frames[3 * v + 2] + lift;
  }
  return planes;
}

/// The largest depth of a vertex behind its plane (0 when every one is in front).
double largestBehind(const std::vector<float>& frames, const std::vector<float>& planes) {
  double largest = 0.0;
  for (std::size_t v = 0; v < frames.size() / 3; ++v) {
    const float* m = &planes[4 * v];
    const double level = double(m[0]) * frames[3 * v] + double(m[1]) * frames[3 * v + 1] +
                         double(m[2]) * frames[3 * v + 2];
    largest = std::max(largest, double(m[3]) - level);
  }
  return largest;
}

/// A copy of `values` in an array of `device`.
DeviceArray onDevice(Device& device, const std::vector<float>& values) {
  DeviceArray array = device.makeArray();
  array.resize<float>(values.size());
  std::copy(values.begin(), values.end(), array.write<float>());
  return array;
}

/// Every vertex of the rest mesh of the sleeve sample.
Mesh sleeveRest() {
  return readObj(testing::dataDir() + "/sleeve/driven_rest.obj");
}

/// `count` frames of the sleeve's simulated cloth, stretched 25% along x and 10% along z about
/// the middle of each frame and shaken by a little noise: strain of every size, every sign.
std::vector<float> stretchedSleeveFrames(int count) {
  std::vector<int> frames;
  for (int f = 1; f <= count; ++f) {
    frames.push_back(f * 5);
  }
  std::vector<float> cloth =
      readFrames(*openPointCache(testing::dataDir() + "/sleeve/test.driven.pc2"), frames);
  std::mt19937 rng(testing::testSeed());
  std::normal_distribution<float> noise(0.0f, 0.001f);
  const std::size_t values = cloth.size() / frames.size();
  for (std::size_t f = 0; f < frames.size(); ++f) {
    float* frame = cloth.data() + f * values;
    double middle[3] = {0.0, 0.0, 0.0};
    for (std::size_t i = 0; i < values; ++i) {
      middle[i % 3] += frame[i] / double(values / 3);
    }
    const double scale[3] = {1.25, 1.0, 1.1};
    for (std::size_t i = 0; i < values; ++i) {
      frame[i] = static_cast<float>(middle[i % 3] + scale[i % 3] * (frame[i] - middle[i % 3])) +
                 noise(rng);
    }
  }
  return cloth;
}

TEST(StrainLimitTables, HoldEveryEdgeTwiceWithItsBandAndShares) {
  const Mesh mesh = strip(3);
  const std::vector<float> weights = {0, 1, 1, 1, 1, 1, 1, 1};
  const StrainLimitTables t = strainLimitTables(mesh, 0.1, 7, 1.5, {}, weights);
  EXPECT_EQ(t.vertexCount, 8);
  EXPECT_EQ(t.iterations, 7);
  ASSERT_EQ(t.start.size(), 9u);
  EXPECT_EQ(t.other.size(), 2u * 10u);  // 3 columns: 10 edges
  // Vertex 0: edges (0, 1) and (0, 4), in meshEdges() order; fixed, so its shares are 0.
  EXPECT_EQ(t.start[0], 0);
  EXPECT_EQ(t.start[1], 2);
  EXPECT_EQ(t.other[0], 1);
  EXPECT_EQ(t.other[1], 4);
  EXPECT_EQ(t.share[0], 0.0f);
  // Vertex 1: (0, 1), (1, 2), (1, 5); its share of the edge to the fixed vertex is all of it.
  EXPECT_EQ(t.other[2], 0);
  EXPECT_EQ(t.share[2], 1.0f);
  EXPECT_EQ(t.share[3], 0.5f);
  EXPECT_FLOAT_EQ(t.lower[3], 0.9f);
  EXPECT_FLOAT_EQ(t.upper[3], 1.1f);
  // Steps: the relaxation over the edges that can move the vertex (none for the fixed one).
  ASSERT_EQ(t.step.size(), 8u);
  EXPECT_EQ(t.step[0], 0.0f);
  EXPECT_EQ(t.step[1], 0.5f);   // 1.5 / 3
  EXPECT_EQ(t.step[4], 0.75f);  // vertex 4: (0, 4) and (4, 5), 1.5 / 2
  testing::expectThrows([&] { strainLimitTables(mesh, 1.0, 7, 1.5); }, ErrorCode::kInternal,
                        "band");
  testing::expectThrows([&] { strainLimitTables(mesh, 0.1, 7, 2.0); }, ErrorCode::kInternal,
                        "relaxation");
  testing::expectThrows([&] { strainLimitTables(mesh, 0.1, 7, 1.5, {}, {1.0f}); },
                        ErrorCode::kInternal, "weights");
}

TEST(StrainLimitTables, ChebyshevWeightsFollowTheRecurrence) {
  // rho = 0.5 from the third iteration: 1, 1, 2 / (2 - 0.25), then 4 / (4 - 0.25 omega).
  const std::vector<float> omega = chebyshevWeights(5, 0.5, 2);
  ASSERT_EQ(omega.size(), 5u);
  EXPECT_EQ(omega[0], 1.0f);
  EXPECT_EQ(omega[1], 1.0f);
  const double w2 = 2.0 / 1.75;
  const double w3 = 4.0 / (4.0 - 0.25 * w2);
  const double w4 = 4.0 / (4.0 - 0.25 * w3);
  EXPECT_FLOAT_EQ(omega[2], float(w2));
  EXPECT_FLOAT_EQ(omega[3], float(w3));
  EXPECT_FLOAT_EQ(omega[4], float(w4));
  EXPECT_EQ(chebyshevWeights(3, 0.0, 1), std::vector<float>(3, 1.0f));
  testing::expectThrows([] { chebyshevWeights(3, 1.0, 1); }, ErrorCode::kInternal, "rho");
  testing::expectThrows([] { chebyshevWeights(3, 0.5, 0); }, ErrorCode::kInternal, "from");
  testing::expectThrows(
      [&] {
        strainLimitTables(strip(2), 0.1, 3, 1.5, {1.0f, 1.2f});
      },
      ErrorCode::kInternal, "Chebyshev");
}

TEST(HostStrainLimit, ChebyshevReachesTheBandInFewerIterations) {
  // 80 iterations on a 16-column strip stretched 30% (a stretch over the whole strip, the
  // hardest case for a local iteration): plain Jacobi leaves the middle edges far outside a 2%
  // band; the accelerated iterations bring every edge within a few percent of it.
  const Mesh mesh = strip(16);
  const std::vector<float> frame = stretched(mesh, 1.3f);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit(1);
  const std::vector<float> plain = limited(*host, strainLimitTables(mesh, 0.02, 80, 1.5), frame);
  const std::vector<float> fast =
      limited(*host, strainLimitTables(mesh, 0.02, 80, 1.5, chebyshevWeights(80, 0.98, 5)), frame);
  std::printf("  largest strain after 80 iterations: %.4f plain, %.4f Chebyshev\n",
              largestStrain(mesh, plain.data()), largestStrain(mesh, fast.data()));
  EXPECT_GT(largestStrain(mesh, plain.data()), 0.15);
  EXPECT_LT(largestStrain(mesh, fast.data()), 0.05);
  for (std::size_t v = 0; v < fast.size() / 3; ++v) {
    EXPECT_NEAR(fast[3 * v + 2], 0.0f, 1e-6f) << v;
  }
}

TEST(HostStrainLimit, BringsAStripStretched30PercentBackIntoTheBand) {
  const Mesh mesh = strip(8);
  const std::vector<float> frame = stretched(mesh, 1.3f);
  ASSERT_NEAR(largestStrain(mesh, frame.data()), 0.3, 1e-6);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit(1);
  // A few iterations only start from the ends; enough of them reach the band everywhere.
  const std::vector<float> few = limited(*host, strainLimitTables(mesh, 0.05, 5, 1.5), frame);
  EXPECT_GT(largestStrain(mesh, few.data()), 0.1);
  const std::vector<float> many = limited(*host, strainLimitTables(mesh, 0.05, 1000, 1.5), frame);
  EXPECT_LE(largestStrain(mesh, many.data()), 0.05 + 1e-4);
  // The strip stays a strip: straight across, in its plane.
  for (std::size_t v = 0; v < many.size() / 3; ++v) {
    EXPECT_NEAR(many[3 * v + 2], 0.0f, 1e-6f) << v;
  }
}

TEST(HostStrainLimit, CompressionGainScalesOnlyTheCorrectionsThatLengthenAnEdge) {
  // One plain iteration: on a strip compressed to 80% every vertex moves half as far with the
  // gain at 0.5 as at 1 (a gain of 0.5 is exact in binary); on one stretched to 120% it moves as
  // far (the corrections that shorten an edge keep their gain).
  const Mesh mesh = strip(8);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit(1);
  for (const float stretch : {0.8f, 1.2f}) {
    const std::vector<float> frame = stretched(mesh, stretch);
    const std::vector<float> full =
        limited(*host, strainLimitTables(mesh, 0.05, 1, 1.5, {}, {}, 1.0), frame);
    const std::vector<float> half =
        limited(*host, strainLimitTables(mesh, 0.05, 1, 1.5, {}, {}, 0.5), frame);
    double moved = 0.0;
    for (std::size_t i = 0; i < frame.size(); ++i) {
      const double fullMove = double(full[i]) - frame[i];
      const double halfMove = double(half[i]) - frame[i];
      moved = std::max(moved, std::fabs(fullMove));
      const double expected = stretch < 1.0f ? 0.5 * fullMove : fullMove;
      // Each result is rounded to float once: half an ulp of coordinates below 8 each, 9.5e-7.
      EXPECT_NEAR(halfMove, expected, 1e-6) << "stretch " << stretch << ", value " << i;
    }
    EXPECT_GT(moved, 1e-3) << "stretch " << stretch;
  }
  testing::expectThrows([&] { strainLimitTables(mesh, 0.05, 1, 1.5, {}, {}, 0.0); },
                        ErrorCode::kInternal, "compression");
  testing::expectThrows([&] { strainLimitTables(mesh, 0.05, 1, 1.5, {}, {}, 1.5); },
                        ErrorCode::kInternal, "compression");
}

TEST(HostStrainLimit, LeavesEdgesInsideTheBandBitwise) {
  // Two strips in one mesh: one stretched 30%, one only 3% (inside a 5% band). The second's
  // vertices never have an edge outside the band: they stay bitwise where they were.
  const Mesh one = strip(6);
  Mesh mesh = one;
  const int n = one.vertexCount();
  mesh.positions.conservativeResize(2 * n, 3);
  mesh.positions.bottomRows(n) = one.positions;
  mesh.positions.bottomRows(n).col(1).array() += 5.0f;
  for (const int v : one.faceVertices) {
    mesh.faceVertices.push_back(v + n);
  }
  for (int f = 1; f <= one.faceCount(); ++f) {
    mesh.faceStart.push_back(mesh.faceStart.back() + 4);
    mesh.faceGroup.push_back(0);
  }
  mesh.triangulate();
  std::vector<float> frame = stretched(mesh, 1.3f);
  const std::vector<float> gentle = stretched(mesh, 1.03f);
  std::copy(gentle.begin() + 3 * n, gentle.end(), frame.begin() + 3 * n);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit(1);
  const std::vector<float> out = limited(*host, strainLimitTables(mesh, 0.05, 50, 1.5), frame);
  EXPECT_TRUE(std::equal(out.begin() + 3 * n, out.end(), frame.begin() + 3 * n));
  EXPECT_FALSE(std::equal(out.begin(), out.begin() + 3 * n, frame.begin()));
}

TEST(HostStrainLimit, KeepsFixedVerticesWhereTheyAre) {
  const Mesh mesh = strip(8);
  const int n = 9;
  std::vector<float> weights(2 * n, 1.0f);
  weights[0] = weights[n] = 0.0f;  // the left end is pinned
  const std::vector<float> frame = stretched(mesh, 1.3f);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit(1);
  const std::vector<float> out =
      limited(*host, strainLimitTables(mesh, 0.05, 1000, 1.5, {}, weights), frame);
  const std::vector<float> fast = limited(
      *host, strainLimitTables(mesh, 0.05, 60, 1.5, chebyshevWeights(60, 0.98, 5), weights), frame);
  for (const int v : {0, n}) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(out[3 * v + a], frame[3 * v + a]) << "vertex " << v;
      EXPECT_EQ(fast[3 * v + a], frame[3 * v + a]) << "vertex " << v << ", Chebyshev";
    }
  }
  EXPECT_LE(largestStrain(mesh, out.data()), 0.05 + 1e-4);
  // The free end came all the way in: the strip is 8 * 1.05 long at most.
  EXPECT_LE(out[3 * (n - 1)], 8.0f * 1.05f + 1e-3f);
}

// A fixed vertex behind its plane moves onto the plane and no further, with the Chebyshev
// acceleration on from the first iteration it can be (the push in iteration 0 is then x_1 - x_0,
// which the acceleration would carry on): it takes no momentum (no edge can move it).
void expectFixedVertexOntoItsPlane(StrainLimitBackend& backend) {
  const Mesh mesh = strip(8);
  const int n = 9;
  std::vector<float> weights(2 * n, 1.0f);
  weights[0] = weights[n] = 0.0f;
  const std::vector<float> frame = stretched(mesh, 1.3f);
  std::vector<float> planes(2 * n * 4, 0.0f);
  planes[2] = 1.0f;  // vertex 0: z >= 0.25
  planes[3] = 0.25f;
  const std::vector<float> out = limited(
      backend, strainLimitTables(mesh, 0.05, 60, 1.5, chebyshevWeights(60, 0.98, 1), weights),
      frame, planes);
  EXPECT_EQ(out[0], frame[0]);
  EXPECT_EQ(out[1], frame[1]);
  EXPECT_EQ(out[2], 0.25f) << "onto the plane, no further";
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(out[3 * n + a], frame[3 * n + a]) << "the other fixed vertex, without a plane";
  }
}

TEST(HostStrainLimit, FixedVerticesMoveOnlyOntoTheirPlanes) {
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit(1);
  expectFixedVertexOntoItsPlane(*host);
}

// A strip stretched 30% with a bump in its middle: without planes the limit flattens the bump;
// with a plane under each of the bump's vertices they stay on it while the rest of the strip
// comes into the band; planes of m = 0 are no planes at all (bitwise).
TEST(HostStrainLimit, KeepsVerticesInFrontOfTheirPlanes) {
  const Mesh mesh = strip(8);
  std::vector<float> frame = stretched(mesh, 1.3f);
  for (const int v : {4, 13}) {
    frame[3 * v + 2] = 0.5f;
  }
  std::vector<float> planes(frame.size() / 3 * 4, 0.0f);
  for (const int v : {4, 13}) {
    planes[4 * v + 2] = 1.0f;
    planes[4 * v + 3] = 0.5f;
  }
  const StrainLimitTables tables = strainLimitTables(mesh, 0.05, 200, 1.5);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit();
  const std::vector<float> free = limited(*host, tables, frame);
  EXPECT_LT(free[3 * 4 + 2], 0.45f) << "without planes the bump flattens";
  const std::vector<float> held = limited(*host, tables, frame, planes);
  EXPECT_LE(largestBehind(held, planes), 1e-6);
  EXPECT_LE(largestStrain(mesh, held.data()), 0.06);
  EXPECT_EQ(limited(*host, tables, frame, std::vector<float>(planes.size(), 0.0f)), free);
}

TEST(HostStrainLimit, TheSameOnAnyThreadsAndChunks) {
  const Mesh mesh = sleeveRest();
  const std::vector<float> frames = stretchedSleeveFrames(6);
  const StrainLimitTables tables = strainLimitTables(mesh, 0.05, 20, 1.5);
  std::unique_ptr<StrainLimitBackend> one = makeHostStrainLimit(1);
  const std::vector<float> reference = limited(*one, tables, frames);
  for (const int threads : {2, 3, 0}) {
    std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit(threads);
    EXPECT_EQ(limited(*host, tables, frames), reference) << threads << " threads";
  }
  // Frame by frame: every frame alone gives what the block gave.
  const std::size_t values = 3 * std::size_t(mesh.vertexCount());
  std::vector<float> single = frames;
  for (std::size_t f = 0; f < 6; ++f) {
    one->limit(1, single.data() + f * values, nullptr, nullptr, 0.0f);
  }
  EXPECT_EQ(single, reference);
  EXPECT_LT(largestStrain(mesh, reference.data()), largestStrain(mesh, frames.data()));
}

TEST(HostStrainLimit, RefusesCallsBeforeUploadAndBadTables) {
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit();
  float x[3] = {0, 0, 0};
  testing::expectThrows([&] { host->limit(1, x, nullptr, nullptr, 0.0f); }, ErrorCode::kInternal,
                        "before upload");
  StrainLimitTables bad = strainLimitTables(strip(2), 0.05, 3, 1.5);
  bad.other[0] = 99;
  testing::expectThrows([&] { host->upload(bad); }, ErrorCode::kInternal, "inconsistent");
}

class ClStrainLimit : public OpenClTest {};

TEST_F(ClStrainLimit, MatchesTheHostOnTheSleeveSample) {
  const Mesh mesh = sleeveRest();
  const std::vector<float> frames = stretchedSleeveFrames(8);
  const double diagonal = boundsDiagonal(mesh);
  std::unique_ptr<Device> clDevice = makeOpenClDevice(context(), device(), queue());
  std::unique_ptr<StrainLimitBackend> cl = clDevice->makeStrainLimit(0);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit();
  EXPECT_EQ(cl->name(), device().getInfo<CL_DEVICE_NAME>());
  // Plain Jacobi, and Chebyshev-accelerated as the stage runs it (negative: -iterations).
  for (const int run : {1, 10, 100, -10, -30}) {
    const int iterations = std::abs(run);
    const StrainLimitTables tables =
        strainLimitTables(mesh, 0.03, iterations, 1.5,
                          run < 0 ? chebyshevWeights(iterations, 0.98, 5) : std::vector<float>{});
    const std::vector<float> onHost = limited(*host, tables, frames);
    const std::vector<float> onCl = limited(*cl, tables, frames);
    const double largest = largestDistance(onCl, onHost);
    std::printf("  %3d iterations%s: OpenCL vs host %.3g of the diagonal\n", iterations,
                run < 0 ? " (Chebyshev)" : "", largest / diagonal);
    EXPECT_LE(largest, kStrainLimitDeviceVsHostRelTol * diagonal) << run;
    EXPECT_GT(largestDistance(onHost, frames), 100 * kStrainLimitDeviceVsHostRelTol * diagonal);

    // On a block that lives on the device: the same as through host memory, bitwise; and
    // frame by frame the same as the whole block.
    DeviceArray block = clDevice->makeArray();
    block.resize<float>(frames.size());
    std::copy(frames.begin(), frames.end(), block.write<float>());
    cl->limitBlock(8, block, nullptr, nullptr, 0.0f);
    const float* blockOut = block.read<float>();
    EXPECT_TRUE(std::equal(onCl.begin(), onCl.end(), blockOut)) << run;
    std::vector<float> single = frames;
    const std::size_t values = 3 * std::size_t(mesh.vertexCount());
    for (std::size_t f = 0; f < 8; ++f) {
      cl->limit(1, single.data() + f * values, nullptr, nullptr, 0.0f);
    }
    EXPECT_EQ(single, onCl) << run;
  }
}

TEST_F(ClStrainLimit, MatchesTheHostWithPlanes) {
  const Mesh mesh = sleeveRest();
  const std::vector<float> frames = stretchedSleeveFrames(4);
  const double diagonal = boundsDiagonal(mesh);
  // Every third vertex held 2 mm above where it starts: active from the first iteration.
  const std::vector<float> planes = floorPlanes(frames, 3, 0.002f);
  const StrainLimitTables tables =
      strainLimitTables(mesh, 0.01, 30, 1.5, chebyshevWeights(30, 0.98, 5));
  std::unique_ptr<Device> clDevice = makeOpenClDevice(context(), device(), queue());
  std::unique_ptr<StrainLimitBackend> cl = clDevice->makeStrainLimit(0);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit();
  const std::vector<float> onHost = limited(*host, tables, frames, planes);
  const std::vector<float> onCl = limited(*cl, tables, frames, planes);
  EXPECT_LE(largestDistance(onCl, onHost), kStrainLimitDeviceVsHostRelTol * diagonal);
  EXPECT_GT(largestDistance(onHost, limited(*host, tables, frames)),
            100 * kStrainLimitDeviceVsHostRelTol * diagonal)
      << "the planes must change the result";
  EXPECT_LE(largestBehind(onHost, planes), 1e-6 * diagonal);
  EXPECT_LE(largestBehind(onCl, planes), 1e-6 * diagonal);
  // On arrays that live on the device: bitwise what the host-memory call gave.
  DeviceArray block = onDevice(*clDevice, frames);
  DeviceArray planeBlock = onDevice(*clDevice, planes);
  cl->limitBlock(4, block, &planeBlock, nullptr, 0.0f);
  EXPECT_TRUE(std::equal(onCl.begin(), onCl.end(), block.read<float>()));

  // The marks of the vertices that stayed within reach, against the distance each moved: a
  // reach that splits the vertices, every third mark 0 beforehand (it stays 0).
  std::vector<double> moved(frames.size() / 3);
  for (std::size_t v = 0; v < moved.size(); ++v) {
    const double dx = double(onHost[3 * v]) - frames[3 * v];
    const double dy = double(onHost[3 * v + 1]) - frames[3 * v + 1];
    const double dz = double(onHost[3 * v + 2]) - frames[3 * v + 2];
    moved[v] = std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  std::vector<double> sorted = moved;
  std::sort(sorted.begin(), sorted.end());
  const float reach = static_cast<float>(sorted[sorted.size() / 2]);
  std::vector<std::int32_t> before(moved.size(), 1);
  for (std::size_t v = 0; v < before.size(); v += 3) {
    before[v] = 0;
  }
  for (StrainLimitBackend* backend : {host.get(), cl.get()}) {
    SCOPED_TRACE(backend->name());
    std::vector<float> positions = frames;
    std::vector<std::int32_t> marks = before;
    backend->upload(tables);
    backend->limit(4, positions.data(), planes.data(), marks.data(), reach);
    int kept = 0;
    int wrong = 0;
    for (std::size_t v = 0; v < marks.size(); ++v) {
      if (std::abs(moved[v] - reach) <= 1e-6 * diagonal) {
        continue;  // a rounding question between float and double
      }
      const int expected = before[v] != 0 && moved[v] < reach ? 1 : 0;
      kept += marks[v];
      wrong += marks[v] != expected ? 1 : 0;
    }
    EXPECT_EQ(wrong, 0) << "of " << marks.size() << " marks";
    EXPECT_GT(kept, int(marks.size()) / 5);
    EXPECT_LT(kept, int(marks.size()) / 2);
  }
}

// The planes' step alone (StrainLimitBackend::keepInFront, the settle stage's): a vertex behind
// its plane lands on it, every other vertex stays bitwise; on the host, on OpenCL and on arrays
// that live on the device. Every third vertex of the sleeve frames gets a floor 1 mm above it
// (behind: it moves up onto it), every fifth one 1 mm below it (in front: it stays).
TEST_F(ClStrainLimit, KeepInFrontMovesOnlyTheVerticesBehindTheirPlanes) {
  const Mesh mesh = sleeveRest();
  const int vertexCount = mesh.vertexCount();
  const std::vector<float> frames = stretchedSleeveFrames(3);
  const double diagonal = boundsDiagonal(mesh);
  std::vector<float> planes = floorPlanes(frames, 3, 0.001f);
  const std::vector<float> below = floorPlanes(frames, 5, -0.001f);
  for (std::size_t v = 0; v < frames.size() / 3; v += 5) {
    if (v % 3 != 0) {
      std::copy(&below[4 * v], &below[4 * v] + 4, &planes[4 * v]);
    }
  }
  std::unique_ptr<Device> clDevice = makeOpenClDevice(context(), device(), queue());
  std::unique_ptr<StrainLimitBackend> cl = clDevice->makeStrainLimit(0);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit();
  std::vector<std::vector<float>> results;
  for (StrainLimitBackend* backend : {host.get(), cl.get()}) {
    SCOPED_TRACE(backend->name());
    std::vector<float> positions = frames;
    backend->keepInFront(3, vertexCount, positions.data(), planes.data());
    int moved = 0;
    int wrong = 0;
    for (std::size_t v = 0; v < frames.size() / 3; ++v) {
      const bool behind = v % 3 == 0;
      const float* x = &positions[3 * v];
      const float* start = &frames[3 * v];
      const bool ok = behind ? x[0] == start[0] && x[1] == start[1] &&
                                   std::abs(double(x[2]) - planes[4 * v + 3]) <= 1e-6 * diagonal
                             : std::equal(x, x + 3, start);
      moved += behind;
      wrong += ok ? 0 : 1;
    }
    EXPECT_EQ(wrong, 0) << "of " << frames.size() / 3 << " vertices";
    EXPECT_GT(moved, 100);
    results.push_back(positions);
  }
  EXPECT_LE(largestDistance(results[0], results[1]), kStrainLimitDeviceVsHostRelTol * diagonal);
  // On arrays that live on the device: bitwise what the host-memory call gave.
  DeviceArray block = onDevice(*clDevice, frames);
  DeviceArray planeBlock = onDevice(*clDevice, planes);
  cl->keepInFrontBlock(3, vertexCount, block, planeBlock);
  EXPECT_TRUE(std::equal(results[1].begin(), results[1].end(), block.read<float>()));
  float x[3] = {0, 0, 0};
  testing::expectThrows([&] { host->keepInFront(-1, 1, x, x); }, ErrorCode::kInternal,
                        "keepInFront");
  testing::expectThrows([&] { cl->keepInFront(1, -1, x, x); }, ErrorCode::kInternal, "keepInFront");
}

TEST_F(ClStrainLimit, MatchesTheHostOnTheStripAndKeepsFixedVertices) {
  const Mesh mesh = strip(8);
  std::vector<float> weights(18, 1.0f);
  weights[0] = weights[9] = 0.0f;
  const std::vector<float> frame = stretched(mesh, 1.3f);
  const StrainLimitTables tables = strainLimitTables(mesh, 0.05, 1000, 1.5, {}, weights);
  std::unique_ptr<Device> clDevice = makeOpenClDevice(context(), device(), queue());
  std::unique_ptr<StrainLimitBackend> cl = clDevice->makeStrainLimit(0);
  std::unique_ptr<StrainLimitBackend> host = makeHostStrainLimit();
  const std::vector<float> onCl = limited(*cl, tables, frame);
  EXPECT_LE(largestDistance(onCl, limited(*host, tables, frame)),
            kStrainLimitDeviceVsHostRelTol * boundsDiagonal(mesh));
  EXPECT_LE(largestStrain(mesh, onCl.data()), 0.05 + 1e-4);
  for (const int v : {0, 9}) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(onCl[3 * v + a], frame[3 * v + a]) << "vertex " << v;
    }
  }
  // Inside the band: bitwise untouched on the device too.
  const std::vector<float> gentle = stretched(mesh, 1.03f);
  EXPECT_EQ(limited(*cl, tables, gentle), gentle);
  // Compressed, with the corrections that lengthen an edge at half gain: as the host.
  const std::vector<float> squeezed = stretched(mesh, 0.8f);
  const StrainLimitTables halfGain = strainLimitTables(mesh, 0.05, 30, 1.5, {}, weights, 0.5);
  const std::vector<float> halfOnCl = limited(*cl, halfGain, squeezed);
  EXPECT_LE(largestDistance(halfOnCl, limited(*host, halfGain, squeezed)),
            kStrainLimitDeviceVsHostRelTol * boundsDiagonal(mesh));
  EXPECT_GT(largestDistance(
                halfOnCl,
                limited(*cl, strainLimitTables(mesh, 0.05, 30, 1.5, {}, weights, 1.0), squeezed)),
            1e-4)
      << "the gain changes the device's result";
  expectFixedVertexOntoItsPlane(*cl);
}

TEST_F(ClStrainLimit, RefusesCallsBeforeUpload) {
  std::unique_ptr<Device> clDevice = makeOpenClDevice(context(), device(), queue());
  std::unique_ptr<StrainLimitBackend> cl = clDevice->makeStrainLimit(0);
  float x[3] = {0, 0, 0};
  testing::expectThrows([&] { cl->limit(1, x, nullptr, nullptr, 0.0f); }, ErrorCode::kInternal,
                        "before upload");
}

}  // namespace
}  // namespace drivenshape
