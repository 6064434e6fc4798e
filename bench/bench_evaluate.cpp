// SPDX-License-Identifier: Apache-2.0
// drivenshape_bench_evaluate: the interactive case. Times Evaluator::evaluate() one frame per
// call (batch 1, what a viewport or a scrubbing animator asks for) on an OpenCL device and on
// the host reference in one run, with the defaults unless told otherwise, and counts the
// host<->device transfers per call. A benchmark, not a test: it asserts nothing, it measures.
//
//   drivenshape_bench_evaluate --db DB --driver CACHE [--frames RANGE] [--device SPEC]
//                              [--batch N] [--repeat N] [--json PATH]

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include <drivenshape/database.h>
#include <drivenshape/device.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/frames.h>
#include <drivenshape/point_cache.h>

#include "json_text.h"

#include "cli_args.h"
#include "device_choice.h"
#include "host_staging.h"
#include "run_main.h"

namespace ds = drivenshape;

namespace {

using Clock = std::chrono::steady_clock;

struct Latency {
  std::vector<double> milliseconds;  ///< per call, sorted
  ds::StageSeconds seconds;          ///< summed over calls
  ds::TransferCounts transfers;      ///< over all calls
  int calls = 0;

  double percentile(double p) const {
    const std::size_t i = static_cast<std::size_t>(p * (milliseconds.size() - 1) + 0.5);
    return milliseconds[i];
  }
};

/// Evaluates `frames` `batch` at a time, `repeat` times over, after one untimed pass (kernel
/// compilation, first-touch allocations).
Latency measure(const ds::Database& db, const ds::EvaluatorSettings& settings, ds::Device& device,
                const std::vector<int>& frames, const std::vector<float>& driver, int batch,
                int repeat) {
  ds::Evaluator evaluator(db, settings, device);
  const std::size_t values = 3 * static_cast<std::size_t>(db.driverVertexCount());
  auto pass = [&](Latency* latency) {
    for (std::size_t begin = 0; begin < frames.size(); begin += batch) {
      const std::size_t count = std::min<std::size_t>(batch, frames.size() - begin);
      const std::vector<int> some(frames.begin() + begin, frames.begin() + begin + count);
      const std::vector<float> in(driver.begin() + begin * values,
                                  driver.begin() + (begin + count) * values);
      const auto start = Clock::now();
      const ds::Evaluation out = evaluator.evaluate(some, in);
      if (latency != nullptr) {
        latency->milliseconds.push_back(
            std::chrono::duration<double, std::milli>(Clock::now() - start).count());
        for (const auto& [stage, value] : out.seconds) {
          latency->seconds[stage] += value;
        }
        ++latency->calls;
      }
    }
  };
  pass(nullptr);
  Latency latency;
  const ds::TransferCounts before = device.transfers();
  for (int r = 0; r < repeat; ++r) {
    pass(&latency);
  }
  const ds::TransferCounts after = device.transfers();
  latency.transfers = {after.uploads - before.uploads, after.downloads - before.downloads,
                       after.uploadBytes - before.uploadBytes,
                       after.downloadBytes - before.downloadBytes};
  std::sort(latency.milliseconds.begin(), latency.milliseconds.end());
  return latency;
}

nlohmann::json report(const std::string& name, const Latency& l, int batch) {
  std::printf("%-40s median %7.2f ms  p90 %7.2f ms  max %7.2f ms  (%5.1f frames/s)\n",
              name.substr(0, 40).c_str(), l.percentile(0.5), l.percentile(0.9),
              l.milliseconds.back(), 1000.0 * batch / l.percentile(0.5));
  std::printf("    per call:");
  nlohmann::json stages;
  for (const auto& [stage, value] : l.seconds) {
    std::printf(" %s %.2f ms", stage.c_str(), 1000.0 * value / l.calls);
    stages[stage] = 1000.0 * value / l.calls;
  }
  std::printf("\n");
  const double calls = l.calls;
  if (l.transfers.uploads + l.transfers.downloads > 0) {
    std::printf("    transfers per call: %.1f uploads (%.1f KiB), %.1f downloads (%.1f KiB)\n",
                l.transfers.uploads / calls, l.transfers.uploadBytes / calls / 1024.0,
                l.transfers.downloads / calls, l.transfers.downloadBytes / calls / 1024.0);
  }
  return {{"device", name},
          {"median_ms", l.percentile(0.5)},
          {"p90_ms", l.percentile(0.9)},
          {"max_ms", l.milliseconds.back()},
          {"stage_ms_per_call", stages},
          {"uploads_per_call", l.transfers.uploads / calls},
          {"downloads_per_call", l.transfers.downloads / calls},
          {"upload_kib_per_call", l.transfers.uploadBytes / calls / 1024.0},
          {"download_kib_per_call", l.transfers.downloadBytes / calls / 1024.0}};
}

int run(const std::vector<std::string>& args) {
  ds::cli::ArgParser parser(
      "drivenshape_bench_evaluate --db DB --driver CACHE",
      "Times Evaluator::evaluate() per call with the default settings on an OpenCL device and "
      "on the host reference, and counts host<->device transfers per call.");
  parser.option("--db", "DB", "database (drivenshape db build)", "", true)
      .option("--driver", "CACHE", "driver cache (.pc2 or name.####.exr)", "", true)
      .option("--frames", "RANGE", "frames to evaluate (default: every frame of the cache)")
      .option("--device", "SPEC", "OpenCL device (auto, cpu, gpu, index, name)", "auto")
      .option("--batch", "N", "frames per evaluate() call", "1")
      .option("--repeat", "N", "timed passes over the frames", "3")
      .option("--json", "PATH", "also write the figures as JSON")
      .settings({"audit", "resolve", "threads"})
      .flag("--no-host", "skip the host reference");
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const ds::Database db = ds::loadDatabase(parser.get("--db"));
  const auto cache = ds::openPointCache(parser.get("--driver"), ds::topologyHash(db.driverMesh));
  const std::vector<int> frames =
      parser.has("--frames") ? ds::parseFrameRange(parser.get("--frames")) : cache->frames();
  const std::vector<float> driver = ds::readFrames(*cache, frames);
  const int batch = parser.getInt("--batch", 1);
  ds::EvaluatorSettings settings;
  ds::cli::readSettings(parser, settings);
  const int repeat = parser.getInt("--repeat", 1);
  std::printf(
      "evaluate(): %zu frames, batch %d, %d passes; driver %d, cloth %d vertices, %d "
      "shapes; rigid alignment, local blend, resolution %s, audit %s\n",
      frames.size(), batch, repeat, db.driverVertexCount(), db.drivenVertexCount(), db.shapeCount(),
      settings.resolve ? "on" : "off", settings.audit ? "on" : "off");
  nlohmann::json json{{"frames", frames.size()},
                      {"audit", settings.audit},
                      {"resolve", settings.resolve},
                      {"batch", batch},
                      {"driver_vertices", db.driverVertexCount()},
                      {"driven_vertices", db.drivenVertexCount()},
                      {"shapes", db.shapeCount()}};
  const std::unique_ptr<ds::Device> device =
      ds::cli::openCliDevice(parser.get("--device"), std::cerr);
  json["opencl"] = report(device->description(),
                          measure(db, settings, *device, frames, driver, batch, repeat), batch);
  if (device->isOpenCl()) {
    // The same device with every block staged through host memory: the transfers before
    // blocks stayed on the device.
    ds::bench::HostStagingDevice staging(*device);
    json["opencl_host_staging"] =
        report("same, staged on host",
               measure(db, settings, staging, frames, driver, batch, repeat), batch);
  }
  if (!parser.has("--no-host")) {
    const std::unique_ptr<ds::Device> host = ds::makeHostDevice();
    json["host"] =
        report("host", measure(db, settings, *host, frames, driver, batch, repeat), batch);
  }
  if (parser.has("--json")) {
    std::ofstream(parser.get("--json")) << ds::jsonText(json, 1) << "\n";
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return drivenshape::cli::runMain("drivenshape_bench_evaluate", argc, argv, run);
}
