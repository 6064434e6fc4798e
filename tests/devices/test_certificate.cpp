// SPDX-License-Identifier: Apache-2.0
// The clearance certificate (ClosestBackend::closestOrClearBlock): against the full exact
// search, the resolution and the inside count must come out bitwise the same, on both backends,
// on the bundled sleeve and on scenes made to break a careless certificate: two tubes that pass
// through each other (points deep inside one tube are far from every surface yet inside), fast
// motion, a mask, float arithmetic, 1 and 2 threads.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <drivenshape/device.h>
#include <drivenshape/device_cl.h>

#include "closest.h"

#include <correction_types.h>

#include "cl_backends.h"
#include "correction_fixture.h"
#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

constexpr float kSkinOffset = 0.002f;

/// closestOrClearBlock of every frame of `scene` (surface already set), with `reach`.
std::vector<SurfaceHit> certifiedHits(ClosestBackend& backend, const PosedScene& scene,
                                      float clearance, std::vector<int>& cleared,
                                      float reach = 0.0f) {
  DeviceArray poses;
  DeviceArray points;
  DeviceArray hits;
  poses.view(scene.poses.data(), scene.poses.size());
  points.view(scene.points.data(), scene.points.size());
  const std::size_t items = static_cast<std::size_t>(scene.frameCount) * scene.pointCount;
  hits.resize<SurfaceHit>(items);
  cleared.assign(static_cast<std::size_t>(scene.frameCount), -1);
  backend.closestOrClearBlock(scene.frameCount, poses, points, clearance, hits, cleared.data(),
                              nullptr, false, reach);
  const SurfaceHit* out = hits.read<SurfaceHit>();
  return std::vector<SurfaceHit>(out, out + items);
}

/// Inside counts per frame of `scene` with `hits`.
std::vector<int> insideCounts(ClosestBackend& backend, const PosedScene& scene,
                              const std::vector<SurfaceHit>& hits) {
  DeviceArray poses;
  DeviceArray points;
  DeviceArray hitArray;
  poses.view(scene.poses.data(), scene.poses.size());
  points.view(scene.points.data(), scene.points.size());
  hitArray.view(hits.data(), hits.size());
  std::vector<int> inside(static_cast<std::size_t>(scene.frameCount), -1);
  backend.countInside(scene.frameCount, poses, hitArray, points, inside.data());
  return inside;
}

bool sameBits(const SurfaceHit& a, const SurfaceHit& b) {
  return std::memcmp(&a, &b, sizeof(SurfaceHit)) == 0;
}

/// What one backend's certified search did on a scene.
struct Outcome {
  long long cleared = 0;
  long long queries = 0;
  long long moved = 0;
  long long inside = 0;
  /// Points that were not cleared although deep inside (signed distance < -2 clearance):
  /// what a certificate that looks at distances only would clear.
  long long deepInside = 0;
};

/// Checks the certified hits of `scene` (cleared[f] of them counted per frame) against the
/// full search's `exact` hits, both made with `backend`'s kernels: every point either has the
/// same hit bits or is a witness whose exact signed distance is >= clearance (and the witnesses
/// are what cleared[] counts); the resolution with offset = clearance moves the same points to
/// the same bits, and the inside counts agree.
Outcome expectVerdicts(ClosestBackend& backend, const PosedScene& scene, float clearance,
                       const std::vector<SurfaceHit>& exact,
                       const std::vector<SurfaceHit>& certified, const std::vector<int>& cleared) {
  const InsideAudit audit(scene.mesh);
  const int vp = scene.mesh.vertexCount();
  const int vd = scene.pointCount;
  Outcome outcome;
  for (int f = 0; f < scene.frameCount; ++f) {
    const std::size_t first = static_cast<std::size_t>(f) * vd;
    std::vector<float> signedDistance(static_cast<std::size_t>(vd));
    audit.signedDistances(&scene.poses[static_cast<std::size_t>(f) * 3 * vp], vd,
                          &scene.points[3 * first], &exact[first], signedDistance.data());
    int witnesses = 0;
    for (int i = 0; i < vd; ++i) {
      const SurfaceHit& hit = certified[first + static_cast<std::size_t>(i)];
      const float distance = signedDistance[static_cast<std::size_t>(i)];
      if (sameBits(hit, exact[first + static_cast<std::size_t>(i)])) {
        outcome.deepInside += distance < -2.0f * std::max(clearance, kSkinOffset) ? 1 : 0;
        continue;
      }
      ++witnesses;
      EXPECT_EQ(hit.u, DS_CERT_THIRD) << "frame " << f << ", point " << i;
      EXPECT_EQ(hit.v, DS_CERT_THIRD) << "frame " << f << ", point " << i;
      EXPECT_GE(distance, clearance)
          << "frame " << f << ", point " << i << " was cleared but its exact signed distance is "
          << distance;
    }
    EXPECT_EQ(witnesses, cleared[static_cast<std::size_t>(f)]) << "frame " << f;
    outcome.cleared += witnesses;
  }
  outcome.queries = static_cast<long long>(scene.frameCount) * vd;

  // The resolution and the inside count, from either set of hits.
  std::vector<float> byExact = scene.points;
  std::vector<float> byCertified = scene.points;
  std::vector<int> movedExact(static_cast<std::size_t>(scene.frameCount), -1);
  std::vector<int> movedCertified(static_cast<std::size_t>(scene.frameCount), -1);
  backend.resolve(scene.frameCount, scene.poses.data(), exact.data(), clearance, byExact.data(),
                  movedExact.data());
  backend.resolve(scene.frameCount, scene.poses.data(), certified.data(), clearance,
                  byCertified.data(), movedCertified.data());
  EXPECT_EQ(movedCertified, movedExact);
  EXPECT_EQ(std::memcmp(byCertified.data(), byExact.data(), byExact.size() * sizeof(float)), 0)
      << "the resolution moved other points or to other bits";
  const std::vector<int> insideExact = insideCounts(backend, scene, exact);
  EXPECT_EQ(insideCounts(backend, scene, certified), insideExact);
  outcome.moved = std::accumulate(movedExact.begin(), movedExact.end(), 0LL);
  outcome.inside = std::accumulate(insideExact.begin(), insideExact.end(), 0LL);
  return outcome;
}

/// Runs the certified search of `scene` with `clearance` on `backend` and checks it against
/// the backend's full search (expectVerdicts).
Outcome expectSameVerdicts(ClosestBackend& backend, const PosedScene& scene, float clearance) {
  SCOPED_TRACE(backend.name() + ", clearance " + std::to_string(clearance));
  const BindingMask all = BindingMask::all(scene.pointCount);
  const std::vector<SurfaceHit> exact = closestHits(backend, scene.mesh, all, scene.frameCount,
                                                    scene.poses.data(), scene.points.data());
  std::vector<int> cleared;
  const std::vector<SurfaceHit> certified = certifiedHits(backend, scene, clearance, cleared);
  return expectVerdicts(backend, scene, clearance, exact, certified, cleared);
}

/// A closed tube of radius r around the segment from `from` to `to`, `rings` x `segments`
/// quads capped by fans, outward-oriented, appended to xyz/faces.
void addTube(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double r, int rings,
             int segments, std::vector<float>& xyz, std::vector<std::vector<int>>& faces) {
  const Eigen::Vector3d axis = (to - from).normalized();
  const Eigen::Vector3d side = axis.unitOrthogonal();
  const Eigen::Vector3d up = axis.cross(side);
  const int base = static_cast<int>(xyz.size() / 3);
  for (int i = 0; i < rings; ++i) {
    const Eigen::Vector3d centre = from + (to - from) * (static_cast<double>(i) / (rings - 1));
    for (int j = 0; j < segments; ++j) {
      const double angle = 2.0 * M_PI * j / segments;
      const Eigen::Vector3d p = centre + r * (std::cos(angle) * side + std::sin(angle) * up);
      xyz.insert(xyz.end(),
                 {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
    }
  }
  const int startCap = static_cast<int>(xyz.size() / 3);
  xyz.insert(xyz.end(), {static_cast<float>(from.x()), static_cast<float>(from.y()),
                         static_cast<float>(from.z())});
  xyz.insert(xyz.end(),
             {static_cast<float>(to.x()), static_cast<float>(to.y()), static_cast<float>(to.z())});
  for (int i = 0; i + 1 < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const int j1 = (j + 1) % segments;
      faces.push_back({base + i * segments + j, base + i * segments + j1,
                       base + (i + 1) * segments + j1, base + (i + 1) * segments + j});
    }
  }
  for (int j = 0; j < segments; ++j) {
    const int j1 = (j + 1) % segments;
    faces.push_back({startCap, base + j1, base + j});
    faces.push_back(
        {startCap + 1, base + (rings - 1) * segments + j, base + (rings - 1) * segments + j1});
  }
}

/// Two capped tubes ("legs") of radius 0.1: A along x through the origin, B along y, which
/// starts 0.6 above A and passes through it to 0.6 below in `frameCount` frames (so B cuts
/// through A in the middle frames, and the jumps are 1.2 / (frameCount - 1) per frame). The
/// points follow their tube: a cloth-like shell at 1.2 r, points on the axis (deep inside,
/// farther than any offset from the surface) and at 0.5 r, and points near the surface (within
/// the skin offset, outside and inside).
PosedScene crossingTubes(int frameCount, std::uint32_t seed) {
  std::vector<float> xyz;
  std::vector<std::vector<int>> faces;
  addTube({-1.0, 0.0, 0.0}, {1.0, 0.0, 0.0}, 0.1, 41, 24, xyz, faces);
  const int tubeA = static_cast<int>(xyz.size() / 3);
  addTube({0.0, -1.0, 0.0}, {0.0, 1.0, 0.0}, 0.1, 41, 24, xyz, faces);
  PosedScene scene;
  scene.mesh = makeMesh(xyz, faces);
  scene.frameCount = frameCount;
  const int vp = scene.mesh.vertexCount();

  // Points around each tube in its own frame (tube A's along x, B's along y), rest positions.
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> along(-0.95, 0.95);
  std::uniform_real_distribution<double> turn(0.0, 2.0 * M_PI);
  const double radii[] = {
      0.12, 0.12, 0.12, 0.0, 0.05, 0.1 + 0.5 * kSkinOffset, 0.1 - 0.5 * kSkinOffset};
  std::vector<Eigen::Vector3d> local;
  std::vector<int> owner;
  for (int tube = 0; tube < 2; ++tube) {
    for (int k = 0; k < 700; ++k) {
      const double r = radii[k % 7];
      const double t = along(rng);
      const double angle = turn(rng);
      const Eigen::Vector3d p = tube == 0
                                    ? Eigen::Vector3d(t, r * std::cos(angle), r * std::sin(angle))
                                    : Eigen::Vector3d(r * std::cos(angle), t, r * std::sin(angle));
      local.push_back(p);
      owner.push_back(tube);
    }
  }
  scene.pointCount = static_cast<int>(local.size());
  for (int f = 0; f < frameCount; ++f) {
    const double lift = 0.6 - 1.2 * f / std::max(frameCount - 1, 1);
    for (int v = 0; v < vp; ++v) {
      for (int a = 0; a < 3; ++a) {
        scene.poses.push_back(scene.mesh.positions(v, a) +
                              (v >= tubeA && a == 2 ? static_cast<float>(lift) : 0.0f));
      }
    }
    for (std::size_t i = 0; i < local.size(); ++i) {
      const Eigen::Vector3d p = local[i] + Eigen::Vector3d(0.0, 0.0, owner[i] == 1 ? lift : 0.0);
      scene.points.insert(scene.points.end(), {static_cast<float>(p.x()), static_cast<float>(p.y()),
                                               static_cast<float>(p.z())});
    }
  }
  return scene;
}

/// The bundled sleeve's driver and simulated cloth on consecutive test frames, with a few cloth
/// vertices pushed into the arm (so that the resolution has work) on every other frame.
PosedScene sleeveScene(int frameCount) {
  std::vector<int> frames(static_cast<std::size_t>(frameCount));
  std::iota(frames.begin(), frames.end(), 0);
  const SleeveData sleeve = loadSleeve(frames);
  PosedScene scene;
  scene.mesh = sleeve.driver;
  scene.frameCount = frameCount;
  scene.pointCount = sleeve.driven.vertexCount();
  scene.poses = sleeve.poses;
  scene.points = sleeve.points;
  const int vp = scene.mesh.vertexCount();
  for (int f = 0; f < frameCount; f += 2) {
    for (int i = f; i < scene.pointCount; i += 97) {
      // Halfway to the driver vertex of the same index: on or inside the arm, or near it.
      const std::size_t k = 3 * (static_cast<std::size_t>(f) * scene.pointCount + i);
      const std::size_t v = 3 * (static_cast<std::size_t>(f) * vp + i % vp);
      for (int a = 0; a < 3; ++a) {
        scene.points[k + a] = 0.5f * (scene.points[k + a] + scene.poses[v + a]);
      }
    }
  }
  return scene;
}

void report(const char* name, const Outcome& o) {
  std::printf("[ certificate ] %s: cleared %lld of %lld (%.1f%%), moved %lld, inside %lld\n", name,
              o.cleared, o.queries, 100.0 * o.cleared / std::max(o.queries, 1LL), o.moved,
              o.inside);
}

TEST_F(CorrectionClTest, CertificateClearsMostOfTheSleeveAndChangesNoVerdict) {
  const PosedScene scene = sleeveScene(24);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    backend->setSurface(scene.mesh, BindingMask::all(scene.pointCount));
    for (const float clearance : {kSkinOffset, 0.0f}) {
      const Outcome outcome = expectSameVerdicts(*backend, scene, clearance);
      report(("sleeve, " + backend->name()).c_str(), outcome);
      // The certificate must do its job (the simulated cloth sits clear of the arm) and leave
      // the pushed vertices to the search.
      EXPECT_GT(outcome.cleared, outcome.queries * 9 / 10);
      EXPECT_GT(outcome.moved, 0);
      EXPECT_LT(outcome.cleared, outcome.queries);
    }
  }
}

TEST_F(CorrectionClTest, CertificateNeverClearsAPointInsideCrossingTubes) {
  // Slow (21 frames: 0.06 per frame) and fast (4 frames: 0.4 per frame, four tube radii).
  for (const int frameCount : {21, 4}) {
    const PosedScene scene = crossingTubes(frameCount, testSeed());
    for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
      backend->setSurface(scene.mesh, BindingMask::all(scene.pointCount));
      const Outcome outcome = expectSameVerdicts(*backend, scene, kSkinOffset);
      report(
          ("crossing tubes, " + std::to_string(frameCount) + " frames, " + backend->name()).c_str(),
          outcome);
      // The axis points are 0.1 from every surface and inside: searched, never cleared.
      EXPECT_GT(outcome.deepInside, scene.frameCount * scene.pointCount / 10);
      EXPECT_GT(outcome.inside, 0);
      if (frameCount == 21) {
        EXPECT_GT(outcome.cleared, outcome.queries / 5);
      }
      expectSameVerdicts(*backend, scene, 0.0f);
    }
  }
}

TEST_F(CorrectionClTest, CertificateOnRandomJumpsAndThreadCounts) {
  // Every frame a random rigid motion plus noise: the motions bound little, so most points are
  // searched; the verdicts still agree. Host backends with 1 and 2 threads clear the same.
  PosedScene scene = crossingTubes(6, testSeed() + 1);
  std::mt19937 rng(testSeed() + 2);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  const int vp = scene.mesh.vertexCount();
  for (int f = 0; f < scene.frameCount; ++f) {
    const Eigen::Matrix3d rotation =
        Eigen::AngleAxisd(0.7 * f, Eigen::Vector3d(1.0, 2.0, 0.5).normalized()).toRotationMatrix();
    const Eigen::Vector3d translation(0.3 * f, -0.2 * f, 0.1);
    const std::size_t poseFirst = static_cast<std::size_t>(f) * 3 * vp;
    const std::size_t pointFirst = static_cast<std::size_t>(f) * 3 * scene.pointCount;
    std::vector<float> pose(scene.poses.begin() + poseFirst,
                            scene.poses.begin() + poseFirst + 3 * vp);
    std::vector<float> points(scene.points.begin() + pointFirst,
                              scene.points.begin() + pointFirst + 3 * scene.pointCount);
    pose = rigidlyMoved(pose, rotation, translation);
    points = rigidlyMoved(points, rotation, translation);
    for (float& x : pose) {
      x += noise(rng);
    }
    std::copy(pose.begin(), pose.end(), scene.poses.begin() + poseFirst);
    std::copy(points.begin(), points.end(), scene.points.begin() + pointFirst);
  }
  std::vector<std::vector<int>> clearedByThreads;
  for (const int threads : {1, 2}) {
    ClosestOptions options;
    options.threads = threads;
    const std::unique_ptr<ClosestBackend> host = makeHostClosest(options);
    host->setSurface(scene.mesh, BindingMask::all(scene.pointCount));
    expectSameVerdicts(*host, scene, kSkinOffset);
    std::vector<int> cleared;
    certifiedHits(*host, scene, kSkinOffset, cleared);
    clearedByThreads.push_back(cleared);
  }
  EXPECT_EQ(clearedByThreads[0], clearedByThreads[1]);
  clBackend()->setSurface(scene.mesh, BindingMask::all(scene.pointCount));
  const Outcome outcome = expectSameVerdicts(*clBackend(), scene, kSkinOffset);
  report("random jumps, OpenCL", outcome);
}

TEST_F(CorrectionClTest, CertificateInFloatArithmeticAndWithAMask) {
  const PosedScene scene = sleeveScene(8);
  ClosestOptions single;
  single.forceSinglePrecision = true;
  const std::unique_ptr<ClosestBackend> cl = makeClClosest(context(), device(), queue(), single);
  cl->setSurface(scene.mesh, BindingMask::all(scene.pointCount));
  const Outcome outcome = expectSameVerdicts(*cl, scene, kSkinOffset);
  report("sleeve, float arithmetic", outcome);
  EXPECT_GT(outcome.cleared, 0);

  // With a binding mask (several trees) nothing is cleared: every hit is the exact one.
  std::mt19937 rng(testSeed());
  const BindingMask mask = randomClassMask(scene.mesh, scene.pointCount, 0, rng);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    const std::vector<SurfaceHit> exact = closestHits(*backend, scene.mesh, mask, scene.frameCount,
                                                      scene.poses.data(), scene.points.data());
    std::vector<int> cleared;
    const std::vector<SurfaceHit> certified = certifiedHits(*backend, scene, kSkinOffset, cleared);
    EXPECT_EQ(cleared, std::vector<int>(static_cast<std::size_t>(scene.frameCount), 0));
    EXPECT_EQ(std::memcmp(certified.data(), exact.data(), exact.size() * sizeof(SurfaceHit)), 0);
  }
}

/// `scene` with every point moved by `distance` in a random direction of its own.
PosedScene movedPoints(const PosedScene& scene, double distance, std::uint32_t seed) {
  PosedScene moved = scene;
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::size_t k = 0; k < moved.points.size(); k += 3) {
    const Eigen::Vector3d way = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
    for (int a = 0; a < 3; ++a) {
      moved.points[k + static_cast<std::size_t>(a)] += static_cast<float>(distance * way[a]);
    }
  }
  return moved;
}

/// A floor facing +z (z = 0, x and y in [-10, 10]) and a wall at x = 8 facing +x, away from the
/// point (0, 0, 6): that point is 6 in front of the floor, and 8 behind the wall. Moved 3.9
/// along +x it is 4.1 behind the wall and nearest to it: inside, by the pseudo-normal's sign (an
/// open driver, as where limbs cross), without coming nearer than 4.1 to the surface.
PosedScene floorAndWallBehind() {
  const std::vector<float> xyz = {-10, -10, 0,  10, -10, 0,  10, 10, 0,  -10, 10,  0,
                                  8,   -10, -1, 8,  10,  -1, 8,  10, 10, 8,   -10, 10};
  PosedScene scene;
  scene.mesh = makeMesh(xyz, {{0, 1, 2, 3}, {4, 5, 6, 7}});
  scene.frameCount = 1;
  scene.poses = xyz;
  scene.pointCount = 1;
  scene.points = {0.0f, 0.0f, 6.0f};
  return scene;
}

TEST_F(CorrectionClTest, CertificateWithAReachHoldsWherePointsMoveWithinIt) {
  // An answer given with a reach r must hold for the point anywhere within r of where it was
  // answered: at clearance - r, with the same verdicts from its witness as from the exact hit of
  // the moved point (the strain limit's resolution keeps such answers). Without the reach, a
  // distance bound alone would not do: on the floor-and-wall scene the point is answered, yet
  // moved 3.9 it is inside.
  const float kClearance = 5.0f;
  const float kReach = 3.9f;
  const PosedScene wall = floorAndWallBehind();
  const PosedScene wallMoved = [&] {
    PosedScene moved = wall;
    moved.points[0] += kReach;
    return moved;
  }();
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(wall.mesh, BindingMask::all(1));
    std::vector<int> cleared;
    certifiedHits(*backend, wall, kClearance, cleared);
    EXPECT_EQ(cleared[0], 1) << "without a reach the point is answered";
    EXPECT_EQ(insideCounts(*backend, wallMoved,
                           closestHits(*backend, wall.mesh, BindingMask::all(1), 1,
                                       wallMoved.poses.data(), wallMoved.points.data()))[0],
              1)
        << "moved, the point is inside";
    certifiedHits(*backend, wall, kClearance, cleared, kReach);
    EXPECT_EQ(cleared[0], 0) << "with the reach the wall is within the walk";
  }

  // The sleeve (2 mm offset, answers at 5 offsets kept within 4) and the crossing tubes: every
  // point moved by just under the reach in its own random direction.
  struct Case {
    const char* name;
    PosedScene scene;
    float clearance;
    float reach;
  };
  const Case cases[] = {
      {"sleeve", sleeveScene(8), 5 * kSkinOffset, 4 * kSkinOffset * 0.999f},
      {"crossing tubes", crossingTubes(21, testSeed()), 5 * kSkinOffset, 4 * kSkinOffset * 0.999f}};
  // The host reference and a device in double arithmetic walk alike: the same points answered.
  const bool deviceInDouble =
      device().getInfo<CL_DEVICE_EXTENSIONS>().find("cl_khr_fp64") != std::string::npos;
  for (const Case& c : cases) {
    const BindingMask all = BindingMask::all(c.scene.pointCount);
    const PosedScene moved = movedPoints(c.scene, c.reach, testSeed());
    std::vector<std::vector<bool>> witnesses;
    for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
      SCOPED_TRACE(std::string(c.name) + ", " + backend->name());
      backend->setSurface(c.scene.mesh, all);
      std::vector<int> cleared;
      const std::vector<SurfaceHit> answered =
          certifiedHits(*backend, c.scene, c.clearance, cleared, c.reach);
      const std::vector<SurfaceHit> exact = closestHits(*backend, moved.mesh, all, moved.frameCount,
                                                        moved.poses.data(), moved.points.data());
      // The moved points keep the witnesses of those answered; the others take their exact hits.
      std::vector<SurfaceHit> kept = exact;
      witnesses.emplace_back(kept.size(), false);
      for (std::size_t k = 0; k < kept.size(); ++k) {
        if (answered[k].u == DS_CERT_THIRD && answered[k].v == DS_CERT_THIRD) {
          kept[k] = answered[k];
          witnesses.back()[k] = true;
        }
      }
      backend->setSurface(c.scene.mesh, all);
      const Outcome outcome =
          expectVerdicts(*backend, moved, c.clearance - c.reach, exact, kept, cleared);
      report((std::string(c.name) + " moved within the reach, " + backend->name()).c_str(),
             outcome);
      // Enough witnesses to check (tight cloth: a quarter of the sleeve is 1 cm clear).
      EXPECT_GT(outcome.cleared, outcome.queries / 5) << "the reach still answers points";
    }
    if (deviceInDouble) {
      EXPECT_TRUE(witnesses[0] == witnesses[1])
          << c.name << ": the host reference and the device answer different points";
    }
  }
}

TEST_F(CorrectionClTest, CertificateRecountAfterTheResolutionKeepsItsAnswers) {
  // The audit's recount after the resolution: points the resolution's call answered without a
  // search keep their hits (the resolution leaves them where they are); the moved ones are
  // answered again. On the host backend and on an OpenCL device's own arrays (the blocks stay
  // on the device), with a 2 cm offset so that many points move.
  const PosedScene scene = sleeveScene(8);
  const float offset = 0.02f;
  const std::size_t items = static_cast<std::size_t>(scene.frameCount) * scene.pointCount;
  std::unique_ptr<Device> host = makeHostDevice();
  std::unique_ptr<Device> cl = makeOpenClDevice(context(), device(), queue());
  for (Device* target : {host.get(), cl.get()}) {
    SCOPED_TRACE(target->description());
    std::unique_ptr<ClosestBackend> backend = target->makeClosest(ClosestOptions());
    backend->setSurface(scene.mesh, BindingMask::all(scene.pointCount));
    DeviceArray poses = target->makeArray();
    DeviceArray points = target->makeArray();
    DeviceArray hits = target->makeArray();
    DeviceArray answered = target->makeArray();
    poses.view(scene.poses.data(), scene.poses.size());
    points.resize<float>(scene.points.size());
    std::copy(scene.points.begin(), scene.points.end(), points.write<float>());
    hits.resize<SurfaceHit>(items);
    answered.resize<std::int32_t>(items);
    std::vector<int> cleared(static_cast<std::size_t>(scene.frameCount));
    std::vector<int> moved(static_cast<std::size_t>(scene.frameCount));
    backend->closestOrClearBlock(scene.frameCount, poses, points, offset, hits, cleared.data(),
                                 &answered, false);
    const long long first = std::accumulate(cleared.begin(), cleared.end(), 0LL);
    backend->resolveBlock(scene.frameCount, poses, hits, offset, points, moved.data());
    backend->closestOrClearBlock(scene.frameCount, poses, points, 0.0f, hits, cleared.data(),
                                 &answered, true);
    const long long second = std::accumulate(cleared.begin(), cleared.end(), 0LL);
    std::vector<int> inside(static_cast<std::size_t>(scene.frameCount), -1);
    backend->countInside(scene.frameCount, poses, hits, points, inside.data());

    PosedScene resolved = scene;
    const float* after = points.read<float>();
    resolved.points.assign(after, after + scene.points.size());
    const std::vector<SurfaceHit> exact =
        closestHits(*hostBackend(), scene.mesh, BindingMask::all(scene.pointCount),
                    scene.frameCount, resolved.poses.data(), resolved.points.data());
    hostBackend()->setSurface(scene.mesh, BindingMask::all(scene.pointCount));
    EXPECT_EQ(inside, insideCounts(*hostBackend(), resolved, exact));
    EXPECT_GT(std::accumulate(moved.begin(), moved.end(), 0LL), 100);
    // Everything the first call answered is kept, and some moved points are answered too.
    EXPECT_GT(second, first);
    EXPECT_GT(first, static_cast<long long>(items) / 10);
  }
}

TEST_F(CorrectionClTest, CertificateFollowsPosesRewrittenInPlace) {
  // The OpenCL backend keeps a block's refitted boxes and cones while the pose array keeps its
  // version (DeviceArray::version): the same array rewritten in place with other frames must
  // give the verdicts of those frames, not of the first ones.
  const PosedScene first = sleeveScene(4);
  // The same frames in the other order, the body 1 cm aside: other boxes, other verdicts.
  PosedScene second = first;
  const std::size_t poseValues = second.poses.size() / static_cast<std::size_t>(first.frameCount);
  const std::size_t pointValues = second.points.size() / static_cast<std::size_t>(first.frameCount);
  for (int f = 0; f < first.frameCount; ++f) {
    const std::size_t from = static_cast<std::size_t>(first.frameCount - 1 - f);
    const std::size_t to = static_cast<std::size_t>(f);
    for (std::size_t k = 0; k < poseValues; ++k) {
      second.poses[to * poseValues + k] =
          first.poses[from * poseValues + k] + (k % 3 == 0 ? 0.01f : 0.0f);
    }
    std::copy_n(&first.points[from * pointValues], pointValues, &second.points[to * pointValues]);
  }
  std::unique_ptr<Device> cl = makeOpenClDevice(context(), device(), queue());
  std::unique_ptr<ClosestBackend> backend = cl->makeClosest(ClosestOptions());
  backend->setSurface(first.mesh, BindingMask::all(first.pointCount));
  const std::size_t items = static_cast<std::size_t>(first.frameCount) * first.pointCount;
  DeviceArray poses = cl->makeArray();
  DeviceArray points = cl->makeArray();
  DeviceArray hits = cl->makeArray();
  poses.resize<float>(first.poses.size());
  points.resize<float>(first.points.size());
  hits.resize<SurfaceHit>(items);
  std::vector<int> cleared(static_cast<std::size_t>(first.frameCount));
  for (const PosedScene* scene : {&first, static_cast<const PosedScene*>(&second)}) {
    std::copy(scene->poses.begin(), scene->poses.end(), poses.write<float>());
    std::copy(scene->points.begin(), scene->points.end(), points.write<float>());
    backend->closestOrClearBlock(scene->frameCount, poses, points, kSkinOffset, hits,
                                 cleared.data());
    const SurfaceHit* out = hits.read<SurfaceHit>();
    const std::vector<SurfaceHit> certified(out, out + items);
    // The full search and the checks on the fixture's OpenCL backend (the same kernels): a
    // second backend, so that `backend` keeps what it refitted.
    const std::vector<SurfaceHit> exact =
        closestHits(*clBackend(), scene->mesh, BindingMask::all(scene->pointCount),
                    scene->frameCount, scene->poses.data(), scene->points.data());
    expectVerdicts(*clBackend(), *scene, kSkinOffset, exact, certified, cleared);
    EXPECT_GT(std::accumulate(cleared.begin(), cleared.end(), 0LL), 0);
  }
}

}  // namespace
}  // namespace drivenshape::testing
