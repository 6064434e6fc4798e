// SPDX-License-Identifier: Apache-2.0
// W3 benchmark (docs/performance.md): position maps at 2048x2048 for 240 frames. Not a test.
//
//   bench_posmap --mesh driven_rest.obj --cache test_public.driven.pc2 [--frames 240]
//                [--res 2048] [--padding 8] [--codec-frames 24] [--repeats 3] [--files 1]
//                [--out DIR]
//
// Reports, in one run on one machine:
//   * the UV rasterisation (once per mesh), min and median of --repeats;
//   * evaluation only (upload, kernels, read back; no files), host reference vs OpenCL on the
//     first OpenCL device, frames/s over the --frames frames (the cache's frames, looped);
//   * per compression: --codec-frames maps written end to end (evaluate on OpenCL + EXR
//     files on all cores), the file size, and the time to write one file on one thread;
//   * end to end for all --frames frames with the default compression (zip).
// Files go to --out (default: a folder under the current one) and are removed afterwards;
// --files 0 stops after the evaluation figures.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/position_map.h>
#include <drivenshape/position_map_backend.h>
#include <drivenshape/position_map_sequence.h>
#include <drivenshape/position_map_tables.h>

#include "cl_backends.h"
#include "stopwatch.h"

namespace {

using namespace drivenshape;
using Clock = std::chrono::steady_clock;

struct Args {
  std::string mesh;
  std::string cache;
  std::string out = "bench_posmap_out";
  int frames = 240;
  int width = 2048;
  int height = 2048;
  int padding = 8;
  int codecFrames = 24;
  int repeats = 3;
  bool files = true;
};

Args parseArgs(int argc, char** argv) {
  Args args;
  for (int i = 1; i < argc; ++i) {
    const std::string name = argv[i];
    if (i + 1 >= argc) {
      DS_THROW(kUsage, "option ", name, " needs a value");
    }
    const std::string value = argv[++i];
    if (name == "--mesh") {
      args.mesh = value;
    } else if (name == "--cache") {
      args.cache = value;
    } else if (name == "--out") {
      args.out = value;
    } else if (name == "--frames") {
      args.frames = std::stoi(value);
    } else if (name == "--res") {
      std::tie(args.width, args.height) = parsePositionMapResolution(value);
    } else if (name == "--padding") {
      args.padding = std::stoi(value);
    } else if (name == "--codec-frames") {
      args.codecFrames = std::stoi(value);
    } else if (name == "--repeats") {
      args.repeats = std::max(1, std::stoi(value));
    } else if (name == "--files") {
      args.files = std::stoi(value) != 0;
    } else {
      DS_THROW(kUsage, "unknown option ", name);
    }
  }
  if (args.mesh.empty() || args.cache.empty()) {
    DS_THROW(kUsage,
             "usage: bench_posmap --mesh M.obj --cache CACHE [--frames 240] [--res 2048] "
             "[--padding 8] [--codec-frames 24] [--repeats 3] [--files 1] [--out DIR]");
  }
  return args;
}

struct Stats {
  double min = 0;
  double median = 0;
};

Stats stats(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return {values.front(), values[values.size() / 2]};
}

struct ClSetup {
  cl::Context context;
  cl::Device device;
  cl::CommandQueue queue;
  std::string name;
};

std::unique_ptr<ClSetup> firstClDevice() {
  try {
    std::vector<cl::Platform> platforms;
    cl::Platform::get(&platforms);
    for (auto& platform : platforms) {
      std::vector<cl::Device> devices;
      platform.getDevices(CL_DEVICE_TYPE_ALL, &devices);
      if (!devices.empty()) {
        auto setup = std::make_unique<ClSetup>();
        setup->device = devices.front();
        setup->context = cl::Context(setup->device);
        setup->queue = cl::CommandQueue(setup->context, setup->device);
        setup->name = setup->device.getInfo<CL_DEVICE_NAME>() + " (" +
                      platform.getInfo<CL_PLATFORM_NAME>() + ")";
        return setup;
      }
    }
  } catch (const cl::Error&) {
  }
  return nullptr;
}

std::unique_ptr<PositionMapBackend> makeBackend(const ClSetup* cl) {
  if (cl == nullptr) {
    return makeHostPositionMaps();
  }
  return makeClPositionMaps(cl->context, cl->device, cl->queue);
}

/// Seconds of evaluate() over all frames, chunk by chunk (blocking read back included).
Stats evaluateTime(PositionMapBackend& backend, const PositionMapTables& tables,
                   const std::vector<float>& xyz, int frames, int chunk, int repeats) {
  const std::size_t vertexFloats = 3 * static_cast<std::size_t>(tables.vertexCount);
  std::vector<float> positions(static_cast<std::size_t>(chunk) * 3 * tables.texelCount());
  backend.evaluate(1, xyz.data(), positions.data(), nullptr);  // warm up
  std::vector<double> times;
  for (int r = 0; r < repeats; ++r) {
    const auto start = Clock::now();
    for (int first = 0; first < frames; first += chunk) {
      const int count = std::min(chunk, frames - first);
      backend.evaluate(count, xyz.data() + static_cast<std::size_t>(first) * vertexFloats,
                       positions.data(), nullptr);
    }
    times.push_back(secondsSince(start));
  }
  return stats(times);
}

std::uintmax_t removeAndMeasure(const std::string& folder, int& files) {
  std::uintmax_t bytes = 0;
  files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    bytes += entry.file_size();
    ++files;
  }
  std::filesystem::remove_all(folder);
  return bytes;
}

int run(const Args& args) {
  const Mesh mesh = readObj(args.mesh);
  const auto cache = openPointCache(args.cache, topologyHash(mesh));
  if (cache->vertexCount() != mesh.vertexCount()) {
    DS_THROW(kInput, args.cache, " has ", cache->vertexCount(), " vertices, the mesh ",
             mesh.vertexCount());
  }
  const std::vector<int> available = cache->frames();
  std::vector<int> frames;
  for (int i = 0; i < args.frames; ++i) {
    frames.push_back(available[static_cast<std::size_t>(i) % available.size()]);
  }
  const std::vector<float> xyz = readFrames(*cache, frames);
  const std::unique_ptr<ClSetup> cl = firstClDevice();
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  std::printf(
      "W3 position maps: %s (%d vertices, %d triangles), %s, %d frames (%zu in the cache, "
      "looped), %dx%d, padding %d\n",
      args.mesh.c_str(), mesh.vertexCount(), mesh.triangleCount(), args.cache.c_str(), args.frames,
      available.size(), args.width, args.height, args.padding);
  std::printf("machine: %u hardware threads; OpenCL device: %s\n\n", threads,
              cl ? cl->name.c_str() : "none (host only)");

  std::vector<double> buildTimes;
  PositionMapTables tables;
  for (int r = 0; r < args.repeats; ++r) {
    const auto start = Clock::now();
    tables = buildPositionMapTables(mesh, args.width, args.height, args.padding, args.mesh);
    buildTimes.push_back(secondsSince(start));
  }
  const Stats build = stats(buildTimes);
  std::printf(
      "UV rasterisation + padding (once per mesh): min %.3f s, median %.3f s; %lld "
      "covered, %lld padded texels%s%s\n\n",
      build.min, build.median, tables.coveredCount, tables.paddedCount,
      tables.overlaps.empty() ? "" : "; ", tables.overlaps.describe().c_str());

  // Frames per launch as the writer chooses them for P only (256 MiB of maps).
  PositionMapOptions options;
  options.width = args.width;
  options.height = args.height;
  options.padding = args.padding;
  const int chunk =
      std::max(1, std::min(16, static_cast<int>((std::size_t{256} << 20) /
                                                (3 * tables.texelCount() * sizeof(float)))));
  std::printf("evaluation only (no files), %d frames per launch, %d repeats:\n", chunk,
              args.repeats);
  auto host = makeHostPositionMaps();
  host->upload(tables);
  const Stats hostTime = evaluateTime(*host, tables, xyz, args.frames, chunk, args.repeats);
  std::printf("  host reference   best %8.1f  median %8.1f frames/s\n", args.frames / hostTime.min,
              args.frames / hostTime.median);
  if (cl) {
    auto device = makeClPositionMaps(cl->context, cl->device, cl->queue);
    device->upload(tables);
    const Stats clTime = evaluateTime(*device, tables, xyz, args.frames, chunk, args.repeats);
    std::printf("  OpenCL           best %8.1f  median %8.1f frames/s  (median %.2fx host)\n",
                args.frames / clTime.min, args.frames / clTime.median,
                hostTime.median / clTime.median);
  }
  std::printf("\n");
  if (!args.files) {
    return 0;
  }

  // Per compression: end-to-end frames/s on all cores, file size, one-file write time.
  std::filesystem::create_directories(args.out);
  std::vector<float> positions(3 * tables.texelCount());
  host->evaluate(1, xyz.data(), positions.data(), nullptr);
  std::printf("per compression (R G B A as FLOAT), %d frames each, %u writer threads:\n",
              args.codecFrames, threads);
  std::printf("  %-5s %12s %16s %18s %14s\n", "codec", "MiB / file", "write 1 file (s)",
              "end to end (fr/s)", "total (s)");
  for (ExrCompression compression :
       {ExrCompression::kZip, ExrCompression::kNone, ExrCompression::kZips, ExrCompression::kPiz}) {
    const std::string folder = args.out + "/" + exrCompressionName(compression);
    std::filesystem::create_directories(folder);
    PositionMapFrameHeader header;
    header.topologyHash = tables.topologyHash;
    header.meshVertexCount = tables.vertexCount;
    header.padding = tables.padding;
    header.compression = compression;
    std::vector<double> oneFile;
    for (int r = 0; r < args.repeats; ++r) {
      const auto start = Clock::now();
      writePositionMapExr(folder + "/single.exr", tables.width, tables.height, positions.data(),
                          tables.coverage.data(), nullptr, header);
      oneFile.push_back(secondsSince(start));
    }
    std::filesystem::remove(folder + "/single.exr");

    options.compression = compression;
    PositionMapWriter writer(mesh, options, makeBackend(cl.get()));
    const std::vector<int> some(
        frames.begin(), frames.begin() + std::min<std::ptrdiff_t>(args.codecFrames, args.frames));
    std::vector<std::string> paths;
    for (std::size_t i = 0; i < some.size(); ++i) {
      paths.push_back(folder + "/m." + std::to_string(i) + ".exr");
    }
    const auto start = Clock::now();
    writer.writeFrames(some, xyz.data(), paths);
    const double total = secondsSince(start);
    int files = 0;
    const std::uintmax_t bytes = removeAndMeasure(folder, files);
    std::printf("  %-5s %12.2f %16.3f %18.2f %14.2f\n", exrCompressionName(compression),
                static_cast<double>(bytes) / files / (1 << 20), stats(oneFile).median,
                some.size() / total, total);
  }
  std::printf("\n");

  // W3 end to end: all frames, zip, evaluation on OpenCL (host without a device).
  {
    options.compression = ExrCompression::kZip;
    PositionMapWriter writer(mesh, options, makeBackend(cl.get()));
    const std::string folder = args.out + "/w3";
    std::filesystem::create_directories(folder);
    std::vector<std::string> paths;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      paths.push_back(folder + "/m." + std::to_string(i) + ".exr");
    }
    const auto start = Clock::now();
    writer.writeFrames(frames, xyz.data(), paths);
    const double total = secondsSince(start);
    int files = 0;
    const std::uintmax_t bytes = removeAndMeasure(folder, files);
    std::printf(
        "W3 end to end (%d frames, zip, %s): %.1f s, %.2f frames/s (evaluate %.1f s, "
        "write %.1f s), %.1f MiB per file\n",
        args.frames, writer.backendName().c_str(), total, args.frames / total,
        writer.evaluateSeconds(), writer.writeSeconds(),
        static_cast<double>(bytes) / files / (1 << 20));
  }
  std::filesystem::remove_all(args.out);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parseArgs(argc, argv));
  } catch (const drivenshape::Error& error) {
    std::fprintf(stderr, "bench_posmap: %s\n", error.what());
    return static_cast<int>(error.code());
  }
}
