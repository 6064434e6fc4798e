// SPDX-License-Identifier: Apache-2.0
#include "correction_fixture.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <thread>

#include "cl_backends.h"
#include "correction_test_util.h"

namespace drivenshape::testing {

ClosestBackend* CorrectionClTest::hostBackend() {
  static std::unique_ptr<ClosestBackend> backend = makeHostClosest();
  return backend.get();
}

ClosestBackend* CorrectionClTest::clBackend() {
  static std::unique_ptr<ClosestBackend> backend = makeClClosest(context(), device(), queue());
  return backend.get();
}

std::vector<std::vector<SurfaceHit>> CorrectionClTest::expectExactOnBothBackends(
    const PosedScene& scene, const BindingMask& mask) {
  const std::vector<double> brute =
      bruteForceAll(scene.mesh, scene.frameCount, scene.poses.data(), scene.points.data(), mask);
  std::vector<std::vector<SurfaceHit>> results;
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    results.push_back(closestHits(*backend, scene.mesh, mask, scene.frameCount, scene.poses.data(),
                                  scene.points.data()));
    expectExact(scene.mesh, scene.frameCount, scene.poses.data(), scene.points.data(), mask,
                results.back(), brute, kClosestDistanceTol);
  }
  return results;
}

void expectDeviceMatchesHost(const std::vector<float>& host, const std::vector<float>& cl,
                             double diagonal) {
  const double error = maxPointError(host, cl);
  EXPECT_LE(error, kDeviceVsHostRelTol * diagonal)
      << "largest |cl - host| " << error << ", tolerance " << kDeviceVsHostRelTol << " x "
      << diagonal;
}

std::vector<double> bruteForceAll(const Mesh& mesh, int frameCount, const float* poses,
                                  const float* points, const BindingMask& mask) {
  const int pointCount = mask.drivenVertexCount();
  const int vertexCount = mesh.vertexCount();
  const int items = frameCount * pointCount;
  std::vector<double> out(static_cast<std::size_t>(items));
  const int threads = std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  for (int w = 0; w < threads; ++w) {
    pool.emplace_back([&, w]() {
      for (int k = w; k < items; k += threads) {
        const int f = k / pointCount;
        const int i = k % pointCount;
        const int c = mask.vertexClass(i);
        static const std::vector<int> all;
        out[static_cast<std::size_t>(k)] =
            bruteForceDistance(mesh, poses + 3L * vertexCount * f, points + 3L * k,
                               c < 0 ? all : mask.classTriangles(c));
      }
    });
  }
  for (std::thread& thread : pool) {
    thread.join();
  }
  return out;
}

void expectExact(const Mesh& mesh, int frameCount, const float* poses, const float* points,
                 const BindingMask& mask, const std::vector<SurfaceHit>& hits,
                 const std::vector<double>& brute, const DistanceTolerance& tolerance) {
  const int pointCount = mask.drivenVertexCount();
  const int vertexCount = mesh.vertexCount();
  int failures = 0;
  double worstStored = 0.0;  // error / allowed error
  double worstPoint = 0.0;
  for (int f = 0; f < frameCount; ++f) {
    const float* pose = poses + 3L * vertexCount * f;
    const float* framePoints = points + 3L * pointCount * f;
    const double scale = sceneScale(pose, vertexCount, framePoints, pointCount);
    for (int i = 0; i < pointCount; ++i) {
      const std::size_t k = static_cast<std::size_t>(f) * pointCount + i;
      const SurfaceHit& hit = hits[k];
      const double expected = brute[k];
      bool ok = hit.triangle >= 0 && hit.triangle < mesh.triangleCount() &&
                mask.allows(i, hit.triangle) && hit.u >= -kBarycentricTol &&
                hit.v >= -kBarycentricTol && hit.u + hit.v <= 1.0 + kBarycentricTol;
      double storedError = 0.0;
      double pointError = 0.0;
      if (ok) {
        const double allowed = tolerance.relative * expected + tolerance.scale * scale;
        const double pointAllowed = std::max(allowed, kHitPointRelTol * (scale + expected));
        storedError = std::fabs(std::sqrt(static_cast<double>(hit.distance2)) - expected) / allowed;
        pointError =
            std::fabs(hitDistance(mesh, pose, framePoints + 3L * i, hit) - expected) / pointAllowed;
        worstStored = std::max(worstStored, storedError);
        worstPoint = std::max(worstPoint, pointError);
        ok = storedError <= 1.0 && pointError <= 1.0;
      }
      if (!ok && ++failures <= 5) {
        ADD_FAILURE() << "frame " << f << " point " << i << ": triangle " << hit.triangle << " (u "
                      << hit.u << ", v " << hit.v << ") at distance "
                      << std::sqrt(static_cast<double>(hit.distance2)) << ", brute force says "
                      << expected << "; error / tolerance: distance " << storedError
                      << ", hit point " << pointError << " (tolerance " << tolerance.relative
                      << " d + " << tolerance.scale << " S); or triangle not allowed";
      }
    }
  }
  EXPECT_EQ(failures, 0) << "of " << frameCount * pointCount << " points";
  std::printf("[ exact    ] %d points; worst error / tolerance: distance %.3f, hit point %.3f\n",
              frameCount * pointCount, worstStored, worstPoint);
}

}  // namespace drivenshape::testing
