// SPDX-License-Identifier: Apache-2.0
// Benchmark (not a test): the wind and mix layers, OpenCL vs the host reference in one run, on
// a synthetic garment grid. Warm-up, then the minimum and median of repeated chunks, the queue
// finished inside the timed region (each call reads its results back).
//   bench_layers [VERTICES=200000] [FRAMES=64] [REPEATS=5]

#include <CL/opencl.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include <drivenshape/layers.h>

#include "cl_backends.h"

#include "layers_test_util.h"

namespace {

using Clock = std::chrono::steady_clock;

template <typename Body>
std::pair<double, double> timeIt(int repeats, Body&& body) {
  body();  // warm-up: program build caches, first-touch allocations
  std::vector<double> seconds;
  for (int r = 0; r < repeats; ++r) {
    const auto start = Clock::now();
    body();
    seconds.push_back(std::chrono::duration<double>(Clock::now() - start).count());
  }
  std::sort(seconds.begin(), seconds.end());
  return {seconds.front(), seconds[seconds.size() / 2]};
}

}  // namespace

int main(int argc, char** argv) {
  namespace ds = drivenshape;
  const int vertices = argc > 1 ? std::atoi(argv[1]) : 200000;
  const int frameCount = argc > 2 ? std::atoi(argv[2]) : 64;
  const int repeats = argc > 3 ? std::atoi(argv[3]) : 5;
  const int columns = 500;
  const int rows = std::max(2, vertices / columns);
  const ds::Mesh mesh = ds::testing::gridMesh(columns, rows, columns / 2, 0.002f);
  const std::vector<float> frames = ds::testing::jitteredFrames(mesh, frameCount, 0.001f, 7);
  std::vector<int> frameNumbers(static_cast<std::size_t>(frameCount));
  for (int f = 0; f < frameCount; ++f) {
    frameNumbers[static_cast<std::size_t>(f)] = 1001 + f;
  }
  std::vector<float> clearance(static_cast<std::size_t>(frameCount) * mesh.vertexCount(), 0.05f);

  ds::LayerTables tables;
  tables.vertexCount = mesh.vertexCount();
  for (int v = 0; v < mesh.vertexCount(); ++v) {
    for (int a = 0; a < 3; ++a) {
      tables.rest.push_back(mesh.positions(v, a) - mesh.positions(0, a));
    }
  }
  tables.mixWeights = ds::smoothWeightMap(ds::readWeightMap("group:left", mesh), mesh, 3);
  tables.windWeights.assign(static_cast<std::size_t>(mesh.vertexCount()), 1.0f);
  ds::WindSettings wind;
  wind.amplitude = 0.01f;
  wind.frequency = 4.0f;
  wind.speed = 1.5;
  wind.octaves = 3;

  std::vector<cl::Platform> platforms;
  cl::Platform::get(&platforms);
  std::vector<cl::Device> devices;
  platforms.at(0).getDevices(CL_DEVICE_TYPE_ALL, &devices);
  cl::Context context(devices.at(0));
  cl::CommandQueue queue(context, devices.at(0));
  auto cl = ds::makeClLayers(context, devices.at(0), queue);
  auto host = ds::makeHostLayers();

  std::printf("layers: %d vertices x %d frames, %d octaves; min / median of %d chunks\n",
              mesh.vertexCount(), frameCount, wind.octaves, repeats);
  for (ds::LayerBackend* backend : {host.get(), cl.get()}) {
    backend->upload(tables);
    std::vector<float> positions = frames;
    const auto [windMin, windMedian] = timeIt(repeats, [&] {
      positions = frames;
      backend->wind(frameCount, frameNumbers.data(), wind, clearance.data(), positions.data());
    });
    const auto [mixMin, mixMedian] = timeIt(repeats, [&] {
      positions = frames;
      backend->mix(frameCount, frames.data(), positions.data());
    });
    std::printf("%-40.40s wind %8.4f / %8.4f s (%7.1f frames/s)   mix %8.4f / %8.4f s\n",
                backend->name().c_str(), windMin, windMedian, frameCount / windMin, mixMin,
                mixMedian);
  }
  return 0;
}
