// SPDX-License-Identifier: Apache-2.0
// Micro-benchmark of the correction stage on W1-like sizes (docs/performance.md): closest
// triangle (host candidate search + exact step) and local-frame transfer for a whole shot, in
// chunks, through the host reference and through OpenCL, in one run on one machine. Not a
// test: run it by hand.
//
//   bench_correction [--frames 100] [--chunk 100] [--vertices 5000] [--points 5000]
//                    [--repeat 5] [--threads 0] [--device NAME] [--single 0|1]
//                    [--host 0|1] [--candidates 0|1]
//
// The scene is an arm-like tube of about --vertices driver vertices (quads, fan triangulated)
// bending a little more every frame, and a looser tube of about --points cloth points around
// it. Each measurement is one pass over all frames (every chunk, results read back, the queue
// finished inside the timed region), after one warm-up pass; it reports min and median over
// --repeat passes and frames per second from the median, and the CPU time of the whole process
// per pass (median; all threads, PoCL's included), which is the fairer figure on a shared
// machine. "candidates" is the host FLANN search alone (the host backend's first step, and the
// OpenCL backend's with DeviceSearch::kCandidates), so closest minus candidates is the exact
// step. "floor" is the least any exact search must do: the distance to the triangle it returns,
// with the answer handed over. The OpenCL backend runs twice: with its default BVH search and with
// the host candidate lists (DeviceSearch::kCandidates), to compare the schemes in one run.
// "clear" is closestOrClearBlock with a 2 mm clearance: the clearance certificate, then the
// search of the points it leaves (src/devices/certificate.cpp).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <sys/resource.h>

#include <drivenshape/error.h>

#include "closest.h"

#include "parallel.h"

#include "cl_backends.h"
#include "opencl_queue.h"

#include "candidates.h"
#include "triangle_distance.h"

namespace {

using drivenshape::BindingMask;
using drivenshape::ClosestBackend;
using drivenshape::Mesh;
using drivenshape::SurfaceHit;

struct Options {
  int frames = 100;
  int chunk = 100;
  int vertices = 5000;
  int points = 5000;
  int repeat = 5;
  int threads = 0;
  std::string device;
  bool single = false;
  bool host = true;        ///< also run the host backend (and the FLANN candidate search)
  bool candidates = true;  ///< also run OpenCL with DeviceSearch::kCandidates
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
    if (flag == "--single" || flag == "--host" || flag == "--candidates") {
      (flag == "--single" ? options.single
       : flag == "--host" ? options.host
                          : options.candidates) = number != 0;
      continue;
    }
    if (number < 0 || (number == 0 && flag != "--threads")) {
      DS_THROW(kUsage, flag, " needs a positive number, got '", value, "'");
    }
    if (flag == "--frames") {
      options.frames = number;
    } else if (flag == "--chunk") {
      options.chunk = number;
    } else if (flag == "--vertices") {
      options.vertices = number;
    } else if (flag == "--points") {
      options.points = number;
    } else if (flag == "--repeat") {
      options.repeat = number;
    } else if (flag == "--threads") {
      options.threads = number;
    } else {
      DS_THROW(kUsage, "unknown flag ", flag);
    }
  }
  return options;
}

/// A tube of `around` x `along` vertices, radius r, length 0.6, along x; quads.
Mesh makeTube(int around, int along, float radius) {
  Mesh mesh;
  mesh.positions.resize(static_cast<long>(around) * along, 3);
  for (int j = 0; j < along; ++j) {
    for (int i = 0; i < around; ++i) {
      const float angle = 6.2831853f * static_cast<float>(i) / static_cast<float>(around);
      mesh.positions.row(static_cast<long>(j) * around + i)
          << 0.6f * static_cast<float>(j) / static_cast<float>(along - 1),
          radius * std::cos(angle), radius * std::sin(angle);
    }
  }
  mesh.faceStart.push_back(0);
  for (int j = 0; j + 1 < along; ++j) {
    for (int i = 0; i < around; ++i) {
      const int a = j * around + i;
      const int b = j * around + (i + 1) % around;
      mesh.faceVertices.insert(mesh.faceVertices.end(), {a, b, b + around, a + around});
      mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
      mesh.faceGroup.push_back(0);
    }
  }
  mesh.groupNames = {"default"};
  mesh.triangulate();
  return mesh;
}

/// Bends positions about the tube's middle by `angle` (radians) in the xy plane, for x > 0.3.
void bend(const float* in, int count, float angle, float* out) {
  for (int v = 0; v < count; ++v) {
    const float x = in[3 * v];
    const float y = in[3 * v + 1];
    const float z = in[3 * v + 2];
    if (x <= 0.3f) {
      out[3 * v] = x;
      out[3 * v + 1] = y;
      out[3 * v + 2] = z;
      continue;
    }
    const float c = std::cos(angle);
    const float s = std::sin(angle);
    out[3 * v] = 0.3f + c * (x - 0.3f) - s * y;
    out[3 * v + 1] = s * (x - 0.3f) + c * y;
    out[3 * v + 2] = z;
  }
}

struct Timing {
  double minMs = 0.0;
  double medianMs = 0.0;
  double cpuMs = 0.0;  ///< median process CPU time (user + system) per pass
};

double processCpuMs() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return 1e3 * static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-3 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

Timing measure(int repeat, const std::function<void()>& pass) {
  pass();  // warm-up: first-use allocations, caches, lazy compilation
  std::vector<double> ms;
  std::vector<double> cpu;
  for (int r = 0; r < repeat; ++r) {
    const double cpuStart = processCpuMs();
    const auto start = std::chrono::steady_clock::now();
    pass();
    const auto stop = std::chrono::steady_clock::now();
    cpu.push_back(processCpuMs() - cpuStart);
    ms.push_back(std::chrono::duration<double, std::milli>(stop - start).count());
  }
  std::sort(ms.begin(), ms.end());
  std::sort(cpu.begin(), cpu.end());
  return {ms.front(), ms[ms.size() / 2], cpu[cpu.size() / 2]};
}

int run(const Options& options) {
  const int around = std::max(8, static_cast<int>(std::lround(std::sqrt(options.vertices * 2.0))));
  const int along = std::max(2, options.vertices / around);
  const Mesh driver = makeTube(around, along, 0.05f);
  const int aroundD = std::max(8, static_cast<int>(std::lround(std::sqrt(options.points * 2.0))));
  const int alongD = std::max(2, options.points / aroundD);
  const Mesh driven = makeTube(aroundD, alongD, 0.056f);
  const int vp = driver.vertexCount();
  const int vd = driven.vertexCount();
  const std::size_t frames = static_cast<std::size_t>(options.frames);

  // Blended driver/cloth bend by angle a_f, the shot's driver by a_f + 0.05 (what the
  // correction moves the cloth to); the cloth carries a little noise.
  std::mt19937 rng(20081112u);
  std::normal_distribution<float> noise(0.0f, 0.002f);
  std::vector<float> blended(frames * 3 * vp);
  std::vector<float> shot(frames * 3 * vp);
  std::vector<float> cloth(frames * 3 * vd);
  for (std::size_t f = 0; f < frames; ++f) {
    const float angle = 1.2f * static_cast<float>(f) / static_cast<float>(frames);
    bend(driver.positions.data(), vp, angle, blended.data() + f * 3 * vp);
    bend(driver.positions.data(), vp, angle + 0.05f, shot.data() + f * 3 * vp);
    bend(driven.positions.data(), vd, angle, cloth.data() + f * 3 * vd);
  }
  for (float& x : cloth) {
    x += noise(rng);
  }
  std::vector<SurfaceHit> hits(frames * vd);
  std::vector<float> corrected(frames * 3 * vd);

  drivenshape::bench::OpenClQueue opened = drivenshape::bench::openClQueue(options.device);
  cl::Device& device = opened.device;
  cl::Context& context = opened.context;
  cl::CommandQueue& queue = opened.queue;

  drivenshape::ClosestOptions closestOptions;
  closestOptions.threads = options.threads;
  closestOptions.forceSinglePrecision = options.single;
  drivenshape::ClosestOptions candidateOptions = closestOptions;
  candidateOptions.deviceSearch = drivenshape::ClosestOptions::DeviceSearch::kCandidates;
  std::unique_ptr<ClosestBackend> backends[] = {
      drivenshape::makeHostClosest(closestOptions),
      drivenshape::makeClClosest(context, device, queue, candidateOptions),
      drivenshape::makeClClosest(context, device, queue, closestOptions)};
  const char* labels[] = {"host", "OpenCL, host candidates", "OpenCL, BVH"};
  const BindingMask mask = BindingMask::all(vd);
  std::printf(
      "bench_correction: driver %d vertices / %d triangles, %d cloth points, %d frames in chunks "
      "of %d, %d passes, %d host threads (0 = all)\n",
      vp, driver.triangleCount(), vd, options.frames, options.chunk, options.repeat,
      options.threads);
  std::printf("OpenCL device: %s (%u compute units)\n", device.getInfo<CL_DEVICE_NAME>().c_str(),
              device.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());

  const auto chunks = [&](const std::function<void(std::size_t, int)>& body) {
    for (std::size_t first = 0; first < frames; first += static_cast<std::size_t>(options.chunk)) {
      body(first, static_cast<int>(std::min<std::size_t>(options.chunk, frames - first)));
    }
    queue.finish();
  };
  struct Row {
    std::string stage;
    std::string backend;
    Timing timing;
  };
  std::vector<Row> rows;

  drivenshape::correction::CandidateSearch search(options.threads);
  search.setSurface(driver, mask);
  drivenshape::correction::CandidateTable table;
  std::size_t candidates = 0;
  if (options.host || options.candidates) {
    rows.push_back({"candidates", "host FLANN", measure(options.repeat, [&] {
                      candidates = 0;
                      chunks([&](std::size_t first, int count) {
                        search.find(count, blended.data() + first * 3 * vp,
                                    cloth.data() + first * 3 * vd, table);
                        candidates += table.triangles.size();
                      });
                    })});
  }

  std::vector<float> local(frames * 3 * vd);
  std::vector<float> resolved(frames * 3 * vd);
  std::vector<int> moved(frames);
  std::vector<SurfaceHit> reference;
  for (int b = 0; b < 3; ++b) {
    if ((b == 0 && !options.host) || (b == 1 && !options.candidates)) {
      continue;
    }
    ClosestBackend& backend = *backends[b];
    const std::string label = labels[b];
    backend.setSurface(driver, mask);
    rows.push_back({"closest", label, measure(options.repeat, [&] {
                      chunks([&](std::size_t first, int count) {
                        backend.closest(count, blended.data() + first * 3 * vp,
                                        cloth.data() + first * 3 * vd, hits.data() + first * vd);
                      });
                    })});
    // Every backend must give the host's triangles (ties aside, which the tie band makes rare).
    if (reference.empty()) {
      reference = hits;
    } else {
      std::size_t differ = 0;
      for (std::size_t k = 0; k < hits.size(); ++k) {
        differ += hits[k].triangle != reference[k].triangle;
      }
      std::printf("%s: %zu of %zu hits on another triangle than the %s's\n", label.c_str(), differ,
                  hits.size(), options.host ? "host" : "OpenCL candidates");
    }
    if (b == 1) {
      continue;  // transfer, rebuild and resolve do not depend on the search
    }
    // The same search where it can matter: points the clearance certificate proves at least
    // the skin offset (2 mm) clear of the driver are not searched.
    long long cleared = 0;
    rows.push_back(
        {"clear", label, measure(options.repeat, [&] {
           cleared = 0;
           chunks([&](std::size_t first, int count) {
             drivenshape::DeviceArray poses;
             drivenshape::DeviceArray points;
             drivenshape::DeviceArray out;
             poses.view(blended.data() + first * 3 * vp, static_cast<std::size_t>(count) * 3 * vp);
             points.view(cloth.data() + first * 3 * vd, static_cast<std::size_t>(count) * 3 * vd);
             out.view(hits.data() + first * vd, static_cast<std::size_t>(count) * vd);
             std::vector<int> counts(static_cast<std::size_t>(count));
             backend.closestOrClearBlock(count, poses, points, 0.002f, out, counts.data());
             for (const int c : counts) {
               cleared += c;
             }
           });
         })});
    std::printf("%s: the certificate cleared %.1f%% of the points (offset 0.002)\n", label.c_str(),
                100.0 * static_cast<double>(cleared) / static_cast<double>(hits.size()));
    rows.push_back({"transfer", label, measure(options.repeat, [&] {
                      chunks([&](std::size_t first, int count) {
                        backend.transfer(
                            count, hits.data() + first * vd, blended.data() + first * 3 * vp,
                            shot.data() + first * 3 * vp, cloth.data() + first * 3 * vd,
                            corrected.data() + first * 3 * vd);
                      });
                    })});
    rows.push_back({"rebuild", label, measure(options.repeat, [&] {
                      chunks([&](std::size_t first, int count) {
                        backend.rebuild(count, hits.data(), shot.data() + first * 3 * vp,
                                        cloth.data() + first * 3 * vd,
                                        local.data() + first * 3 * vd);
                      });
                    })});
    rows.push_back({"resolve", label, measure(options.repeat, [&] {
                      resolved = cloth;
                      chunks([&](std::size_t first, int count) {
                        backend.resolve(count, blended.data() + first * 3 * vp,
                                        hits.data() + first * vd, 0.002f,
                                        resolved.data() + first * 3 * vd, moved.data() + first);
                      });
                    })});
  }

  // The floor of any exact search: the distance to the triangle it returns, measured once per
  // point with the answer handed over (no search, no verification). Compare it with the
  // transfer and with the blend stage (bench_stages) to see what a per-frame exact search can
  // cost at best on this machine.
  std::vector<double> oracle(frames * vd);
  rows.push_back({"floor", "host, answer given", measure(options.repeat, [&] {
                    drivenshape::parallelFor(options.frames, options.threads, [&](int f) {
                      const float* pose = blended.data() + static_cast<std::size_t>(f) * 3 * vp;
                      const float* points = cloth.data() + static_cast<std::size_t>(f) * 3 * vd;
                      for (int i = 0; i < vd; ++i) {
                        const std::size_t k = static_cast<std::size_t>(f) * vd + i;
                        const int t = hits[k].triangle;
                        double u = 0.0;
                        double v = 0.0;
                        oracle[k] = drivenshape::correction::triangleDistance2(
                            drivenshape::correction::loadPoint(points, i),
                            drivenshape::correction::loadPoint(pose, driver.triangles(t, 0)),
                            drivenshape::correction::loadPoint(pose, driver.triangles(t, 1)),
                            drivenshape::correction::loadPoint(pose, driver.triangles(t, 2)), u, v);
                      }
                    });
                  })});

  std::printf("candidates per point: %.1f\n",
              static_cast<double>(candidates) / (static_cast<double>(frames) * vd));
  std::printf("%-11s %-24s %10s %10s %10s %12s %12s\n", "stage", "backend", "min ms", "median ms",
              "frames/s", "CPU ms", "CPU ms/frame");
  for (const Row& row : rows) {
    std::printf("%-11s %-24s %10.2f %10.2f %10.1f %12.1f %12.3f\n", row.stage.c_str(),
                row.backend.c_str(), row.timing.minMs, row.timing.medianMs,
                1000.0 * static_cast<double>(frames) / row.timing.medianMs, row.timing.cpuMs,
                row.timing.cpuMs / static_cast<double>(frames));
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse(argc, argv));
  } catch (const drivenshape::Error& error) {
    std::fprintf(stderr, "bench_correction: %s\n", error.what());
    return static_cast<int>(error.code());
  } catch (const cl::Error& error) {
    std::fprintf(stderr, "bench_correction: OpenCL error in %s (%d)\n", error.what(), error.err());
    return static_cast<int>(drivenshape::ErrorCode::kDevice);
  }
}
