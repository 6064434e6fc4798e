// SPDX-License-Identifier: Apache-2.0
// check_closest_exact: the closest-triangle exactness check on real data that cannot ship with
// the tests (e.g. a generated trousers clip, scripts/validation). For every frame, every driven
// vertex is queried against the driver pose of the same frame through the library (OpenCL on the
// first device, or the host path with --host) and through the independent brute-force oracle of the
// tests; distances must agree within kClosestDistanceTol for 100% of vertices.
//
//   check_closest_exact DRIVER.obj DRIVER.pc2 DRIVEN.pc2 [--host] [--every N]
//
// Prints per-frame mismatches and a summary; exit 0 when every vertex agrees, 1 otherwise.

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

#include "closest.h"

#include "cl_backends.h"

#include "correction_test_util.h"

namespace ds = drivenshape;

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr,
                 "usage: check_closest_exact DRIVER.obj DRIVER.pc2 DRIVEN.pc2 [--host] "
                 "[--every N]\n");
    return 2;
  }
  bool host = false;
  int every = 1;
  for (int i = 4; i < argc; ++i) {
    if (std::strcmp(argv[i], "--host") == 0) {
      host = true;
    } else if (std::strcmp(argv[i], "--every") == 0 && i + 1 < argc) {
      every = std::max(1, std::atoi(argv[++i]));
    }
  }
  try {
    const ds::Mesh mesh = ds::readObj(argv[1]);
    const auto poses = ds::openPointCache(argv[2]);
    const auto points = ds::openPointCache(argv[3]);
    std::unique_ptr<ds::ClosestBackend> backend;
    cl::Context context;
    cl::CommandQueue queue;
    if (host) {
      backend = ds::makeHostClosest();
    } else {
      std::vector<cl::Platform> platforms;
      cl::Platform::get(&platforms);
      std::vector<cl::Device> devices;
      platforms.at(0).getDevices(CL_DEVICE_TYPE_ALL, &devices);
      context = cl::Context(devices.at(0));
      queue = cl::CommandQueue(context, devices.at(0));
      backend = ds::makeClClosest(context, devices.at(0), queue);
    }
    const int vd = points->vertexCount();
    backend->setSurface(mesh, ds::BindingMask::all(vd));
    std::vector<float> pose(mesh.vertexCount() * 3), cloth(vd * 3);
    std::vector<ds::SurfaceHit> hits(vd);
    long checked = 0, mismatched = 0;
    double worst = 0;
    const std::vector<int> frames = poses->frames();
    for (std::size_t f = 0; f < frames.size(); f += every) {
      poses->readFrame(frames[f], pose.data());
      points->readFrame(frames[f], cloth.data());
      backend->closest(1, pose.data(), cloth.data(), hits.data());
      const double scale =
          ds::testing::sceneScale(pose.data(), mesh.vertexCount(), cloth.data(), vd);
      std::vector<long> bad(2, 0);
      std::vector<double> worstOf(2, 0.0);
      auto work = [&](int part) {
        for (int v = part; v < vd; v += 2) {
          const double truth = ds::testing::bruteForceDistance(mesh, pose.data(), &cloth[3 * v]);
          const double got = std::sqrt(static_cast<double>(hits[v].distance2));
          const double allowed = ds::testing::kClosestDistanceTol.relative * truth +
                                 ds::testing::kClosestDistanceTol.scale * scale;
          const double error = std::abs(got - truth);
          worstOf[part] = std::max(worstOf[part], error / allowed);
          if (error > allowed) {
            ++bad[part];
          }
        }
      };
      std::thread second(work, 1);
      work(0);
      second.join();
      checked += vd;
      mismatched += bad[0] + bad[1];
      worst = std::max({worst, worstOf[0], worstOf[1]});
      if (bad[0] + bad[1] > 0) {
        std::printf("frame %d: %ld of %d vertices disagree with brute force\n", frames[f],
                    bad[0] + bad[1], vd);
      }
    }
    std::printf(
        "%s: %ld vertex queries over %zu frames, %ld disagree with brute force; worst "
        "error %.3g of the tolerance\n",
        backend->name().c_str(), checked, (frames.size() + every - 1) / every, mismatched, worst);
    return mismatched == 0 ? 0 : 1;
  } catch (const ds::Error& error) {
    std::fprintf(stderr, "check_closest_exact: %s\n", error.what());
    return 3;
  }
}
