// SPDX-License-Identifier: Apache-2.0
// Micro-benchmark of the per-frame stages on W1-like sizes (docs/performance.md): project and
// blend for a whole shot, in chunks, through the host reference and through OpenCL, in one run
// on one machine. Not a test: run it by hand.
//
//   bench_stages [--frames 1000] [--chunk 250] [--vertices 5000] [--shapes 30] [--repeat 5]
//                [--device NAME]
//
// Each measurement is one pass over all frames (every chunk, results read back, the queue
// finished inside the timed region), after one warm-up pass; it reports min and median wall
// time over --repeat passes, the median process CPU time (all threads; on a shared machine
// cpu < wall x cores shows the run was starved) and frames per second from the median.

#include <drivenshape/error.h>

#include "cl_backends.h"
#include "opencl_queue.h"
#include "stages.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace {

using drivenshape::ShapeTables;
using drivenshape::StageBackend;

struct Options {
  int frames = 1000;
  int chunk = 250;
  int vertices = 5000;
  int shapes = 30;
  int repeat = 5;
  std::string device;
};

Options parse(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (i + 1 >= argc) {
      DS_THROW(kUsage, flag, " needs a value");
    }
    const char* value = argv[++i];
    if (flag == "--device") {
      options.device = value;
      continue;
    }
    const int number = std::atoi(value);
    if (number < 1) {
      DS_THROW(kUsage, flag, " needs a positive number, got '", value, "'");
    }
    if (flag == "--frames") {
      options.frames = number;
    } else if (flag == "--chunk") {
      options.chunk = number;
    } else if (flag == "--vertices") {
      options.vertices = number;
    } else if (flag == "--shapes") {
      options.shapes = number;
    } else if (flag == "--repeat") {
      options.repeat = number;
    } else {
      DS_THROW(kUsage, "unknown flag ", flag);
    }
  }
  return options;
}

// Positions like a character 100 units from the origin; shapes deviate by ~0.1.
ShapeTables makeTables(const Options& options, std::mt19937& rng) {
  std::uniform_real_distribution<float> box(100.0f, 102.0f);
  std::normal_distribution<float> deviation(0.0f, 0.1f);
  const std::size_t n = 3 * static_cast<std::size_t>(options.vertices);
  const std::size_t k = static_cast<std::size_t>(options.shapes);
  ShapeTables tables;
  tables.driverVertexCount = options.vertices;
  tables.drivenVertexCount = options.vertices;
  tables.shapeCount = options.shapes;
  std::vector<float> rest(n);
  for (std::vector<float>* shapes : {&tables.driverShapes, &tables.drivenShapes}) {
    for (float& x : rest) {
      x = box(rng);
    }
    for (std::size_t i = 0; i < k; ++i) {
      for (float x : rest) {
        shapes->push_back(x + deviation(rng));
      }
    }
  }
  tables.center.assign(tables.driverShapes.begin(),
                       tables.driverShapes.begin() + static_cast<std::ptrdiff_t>(n));
  tables.projectionRows.resize((k - 1) * n);
  for (float& x : tables.projectionRows) {
    x = deviation(rng);
  }
  return tables;
}

struct Timing {
  double minMs = 0.0;
  double medianMs = 0.0;
  double medianCpuMs = 0.0;  // process CPU time, all threads: tells a busy machine apart
};

Timing measure(int repeat, const std::function<void()>& pass) {
  pass();  // warm-up: first-use allocations, caches, lazy compilation
  std::vector<double> ms;
  std::vector<double> cpuMs;
  for (int r = 0; r < repeat; ++r) {
    const std::clock_t cpuStart = std::clock();
    const auto start = std::chrono::steady_clock::now();
    pass();
    const auto stop = std::chrono::steady_clock::now();
    const std::clock_t cpuStop = std::clock();
    ms.push_back(std::chrono::duration<double, std::milli>(stop - start).count());
    cpuMs.push_back(1000.0 * static_cast<double>(cpuStop - cpuStart) / CLOCKS_PER_SEC);
  }
  std::sort(ms.begin(), ms.end());
  std::sort(cpuMs.begin(), cpuMs.end());
  return {ms.front(), ms[ms.size() / 2], cpuMs[cpuMs.size() / 2]};
}

struct Row {
  std::string stage;
  std::string backend;
  Timing timing;
};

int run(const Options& options) {
  std::mt19937 rng(20081112u);
  const ShapeTables tables = makeTables(options, rng);
  const std::size_t n = 3 * static_cast<std::size_t>(options.vertices);
  const std::size_t k = static_cast<std::size_t>(options.shapes);
  const std::size_t frames = static_cast<std::size_t>(options.frames);

  std::vector<float> driverFrames(frames * n);
  std::uniform_real_distribution<float> box(100.0f, 102.0f);
  for (float& x : driverFrames) {
    x = box(rng);
  }
  std::vector<float> weights(frames * k);
  std::exponential_distribution<float> draw(1.0f);
  for (std::size_t f = 0; f < frames; ++f) {
    float sum = 0.0f;
    for (std::size_t i = 0; i < k; ++i) {
      sum += weights[f * k + i] = draw(rng);
    }
    for (std::size_t i = 0; i < k; ++i) {
      weights[f * k + i] /= sum;
    }
  }
  std::vector<float> projections(frames * (k - 1));
  std::vector<float> norms(frames * 2);
  std::vector<float> driven(frames * n);
  std::vector<float> driver(frames * n);

  // The device: the first one, or the first whose name contains --device (the library never
  // picks one; this program does).
  drivenshape::bench::OpenClQueue opened = drivenshape::bench::openClQueue(options.device);
  cl::Device& device = opened.device;
  cl::Context& context = opened.context;
  cl::CommandQueue& queue = opened.queue;

  std::unique_ptr<StageBackend> backends[] = {drivenshape::makeHostStages(),
                                              drivenshape::makeClStages(context, device, queue)};
  std::printf("bench_stages: Vp = Vd = %d, k = %d, %d frames in chunks of %d, %d passes\n",
              options.vertices, options.shapes, options.frames, options.chunk, options.repeat);
  std::printf("OpenCL device: %s (%u compute units)\n", device.getInfo<CL_DEVICE_NAME>().c_str(),
              device.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());

  std::vector<Row> rows;
  for (auto& backend : backends) {
    backend->upload(tables);
    const auto chunks = [&](const std::function<void(std::size_t, int)>& body) {
      for (std::size_t first = 0; first < frames;
           first += static_cast<std::size_t>(options.chunk)) {
        body(first, static_cast<int>(std::min<std::size_t>(options.chunk, frames - first)));
      }
      queue.finish();  // no-op for the host; the stages read back blocking anyway
    };
    rows.push_back({"project", backend->name(), measure(options.repeat, [&] {
                      chunks([&](std::size_t first, int count) {
                        backend->project(count, driverFrames.data() + first * n,
                                         projections.data() + first * (k - 1),
                                         norms.data() + first * 2);
                      });
                    })});
    rows.push_back({"blend driven+driver", backend->name(), measure(options.repeat, [&] {
                      chunks([&](std::size_t first, int count) {
                        backend->blend(count, weights.data() + first * k, driven.data() + first * n,
                                       driver.data() + first * n);
                      });
                    })});
  }

  std::printf("%-20s %-32s %10s %10s %10s %12s %8s\n", "stage", "backend", "min ms", "median ms",
              "cpu ms", "frames/s", "speedup");
  for (const Row& row : rows) {
    double hostMedian = row.timing.medianMs;
    for (const Row& other : rows) {
      if (other.stage == row.stage && other.backend == "host") {
        hostMedian = other.timing.medianMs;
      }
    }
    std::printf("%-20s %-32.32s %10.1f %10.1f %10.1f %12.0f %7.1fx\n", row.stage.c_str(),
                row.backend.c_str(), row.timing.minMs, row.timing.medianMs, row.timing.medianCpuMs,
                1000.0 * options.frames / row.timing.medianMs, hostMedian / row.timing.medianMs);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse(argc, argv));
  } catch (const drivenshape::Error& error) {
    std::fprintf(stderr, "bench_stages: %s error: %s\n", drivenshape::errorCodeName(error.code()),
                 error.what());
    return static_cast<int>(error.code());
  } catch (const cl::Error& error) {
    std::fprintf(stderr, "bench_stages: OpenCL error: %s returned %s\n", error.what(),
                 drivenshape::clErrorName(error.err()));
    return static_cast<int>(drivenshape::ErrorCode::kDevice);
  }
}
