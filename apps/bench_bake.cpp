// SPDX-License-Identifier: Apache-2.0
// drivenshape_bench: bakes a synthetic shot of the DESIGN.md workloads through OpenCL and
// through the host reference in one run, and reports per-stage times and frames per second.
// A benchmark, not a test: it asserts nothing, it measures.
//
//   drivenshape_bench [--workload W1] [--frames N] [--device SPEC] [--json PATH] [--keep DIR]
//
// The synthetic character is a bending tube (driver) inside a looser tube (driven); database
// shapes are random bends, the shot a smooth sweep through bends. Generated deterministically.

#include <unistd.h>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <random>

#include <drivenshape/bake.h>
#include <drivenshape/database.h>
#include <drivenshape/error.h>
#include <drivenshape/point_cache.h>

#include "json_text.h"

#include "cli_args.h"
#include "device_choice.h"
#include "host_staging.h"
#include "run_main.h"
#include "synthetic_workload.h"

namespace ds = drivenshape;
namespace fs = std::filesystem;

namespace {

using ds::bench::bend;
using ds::bench::tube;
using ds::bench::Workload;
using ds::bench::workload;

/// Resets the kernel's peak-RSS mark of this process (Linux >= 4.0), so the next peakRssMiB()
/// reads the peak of what ran in between.
void resetPeakRss() {
  std::ofstream("/proc/self/clear_refs") << "5";
}

/// The process's peak resident set size (VmHWM) in MiB, or -1 where /proc does not tell.
double peakRssMiB() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) {
      return std::stod(line.substr(6)) / 1024.0;  // kB
    }
  }
  return -1.0;
}

/// The evaluator's stages in the columns of the table (stages that did not run show 0).
const char* const kStages[] = {"align",   "project", "weights", "blend",
                               "correct", "resolve", "layers",  "audit"};

/// The closest-point queries of the resolution and the audit over the bake, and the fraction
/// the clearance certificate answered without a search (0 when there were none).
std::pair<long long, double> clearedFraction(const ds::BakeResult& r) {
  long long queries = 0;
  long long cleared = 0;
  for (const ds::FrameRecord& record : r.frames) {
    queries += record.closestQueries;
    cleared += record.closestCleared;
  }
  return {queries, queries > 0 ? static_cast<double>(cleared) / static_cast<double>(queries) : 0.0};
}

nlohmann::json timesJson(const ds::BakeResult& r, double rssMiB) {
  nlohmann::json json{
      {"peak_rss_mib", rssMiB},          {"read", r.times.read},
      {"write", r.times.write},          {"read_wait", r.times.readWait},
      {"write_wait", r.times.writeWait}, {"setup", r.times.setup},
      {"total", r.times.total},          {"frames_per_second", r.baked / r.times.total}};
  for (const char* stage : kStages) {
    json[stage] = r.times.stage(stage);
  }
  const auto [queries, fraction] = clearedFraction(r);
  json["closest_queries"] = queries;
  json["closest_cleared_fraction"] = fraction;
  return json;
}

/// Host<->device copies per launch batch between two counts (setup uploads included, spread
/// over the batches), printed and returned.
nlohmann::json transfersPerBatch(const std::string& name, const ds::TransferCounts& before,
                                 const ds::TransferCounts& after, int frames, int batch) {
  const double batches = std::ceil(static_cast<double>(frames) / batch);
  const nlohmann::json transfers{
      {"batches", batches},
      {"uploads_per_batch", (after.uploads - before.uploads) / batches},
      {"downloads_per_batch", (after.downloads - before.downloads) / batches},
      {"upload_mib_per_batch", (after.uploadBytes - before.uploadBytes) / batches / 1048576.0},
      {"download_mib_per_batch",
       (after.downloadBytes - before.downloadBytes) / batches / 1048576.0}};
  std::printf(
      "%s transfers per batch of %d frames: %.1f uploads (%.2f MiB), %.1f downloads "
      "(%.2f MiB)\n",
      name.c_str(), batch, transfers["uploads_per_batch"].get<double>(),
      transfers["upload_mib_per_batch"].get<double>(),
      transfers["downloads_per_batch"].get<double>(),
      transfers["download_mib_per_batch"].get<double>());
  return transfers;
}

void printHeader() {
  std::printf("%-24s %6s %6s %6s %6s %6s %7s %7s %6s %6s %6s %6s %6s %8s %9s %7s %8s\n",
              "path (s per stage)", "read", "align", "proj", "QP", "blend", "correct", "resolve",
              "layers", "audit", "write", "wait", "setup", "total", "frames/s", "RSS MiB",
              "cleared");
}

/// Read and write run on I/O tasks beside the other stages; "wait" is the time the bake
/// thread spent waiting for them.
void printRow(const std::string& name, const ds::BakeResult& r, double rssMiB) {
  const auto [queries, fraction] = clearedFraction(r);
  char cleared[16] = "-";
  if (queries > 0) {
    std::snprintf(cleared, sizeof(cleared), "%.1f%%", 100.0 * fraction);
  }
  std::printf(
      "%-24s %6.3f %6.3f %6.3f %6.3f %6.3f %7.3f %7.3f %6.3f %6.3f %6.3f %6.3f %6.3f %8.3f "
      "%9.1f %7.0f %8s\n",
      name.substr(0, 24).c_str(), r.times.read, r.times.stage("align"), r.times.stage("project"),
      r.times.stage("weights"), r.times.stage("blend"), r.times.stage("correct"),
      r.times.stage("resolve"), r.times.stage("layers"), r.times.stage("audit"), r.times.write,
      r.times.readWait + r.times.writeWait, r.times.setup, r.times.total, r.baked / r.times.total,
      rssMiB, cleared);
}

/// Bakes `options` with the clearance certificate off into `folder`, prints its row and
/// returns its figures.
nlohmann::json bakeFullSearch(const ds::Database& db, const ds::PointCacheReader& shot,
                              ds::Device& device, ds::BakeOptions options, const fs::path& folder,
                              const std::string& name) {
  options.evaluator.clearanceCertificate = false;
  options.outputPattern = (folder / "shot.####.exr").string();
  resetPeakRss();
  const ds::BakeResult result = ds::bake(db, shot, device, options);
  const double rss = peakRssMiB();
  printRow(name, result, rss);
  return timesJson(result, rss);
}

/// Whether the `frames` outputs in folders `a` and `b` are the same bytes (printed when not).
bool sameFiles(const fs::path& a, const fs::path& b, int frames, const std::string& name) {
  for (int f = 1; f <= frames; ++f) {
    char file[32];
    std::snprintf(file, sizeof(file), "shot.%04d.exr", f);
    std::ifstream first(a / file, std::ios::binary);
    std::ifstream second(b / file, std::ios::binary);
    const std::string x((std::istreambuf_iterator<char>(first)), std::istreambuf_iterator<char>());
    const std::string y((std::istreambuf_iterator<char>(second)), std::istreambuf_iterator<char>());
    if (x.empty() || x != y) {
      std::printf("%s: frame %d differs from the full search's\n", name.c_str(), f);
      return false;
    }
  }
  std::printf("%s: all %d frames are the same bytes as the full search's\n", name.c_str(), frames);
  return true;
}

int runBench(const std::vector<std::string>& args) {
  ds::cli::ArgParser parser("drivenshape_bench [options]",
                            "Bakes a synthetic workload through OpenCL and the host reference in "
                            "one run; prints per-stage seconds and frames/s.");
  parser.option("--workload", "W", "W1 (5k/5k vertices, 30 shapes, 1000 frames) or W2", "W1")
      .option("--frames", "N", "override the workload's frame count")
      .option("--device", "SPEC", "OpenCL device (as for bake)", "auto")
      .option("--batch", "N", "frames per launch", "64")
      .option("--threads", "N", "host threads (0 = all)", "0")
      .option("--compression", "C", "EXR compression", "zip")
      .option("--zip-encoder", "E", "libdeflate or openexr (as for bake)", "libdeflate")
      .option("--json", "PATH", "also write the figures as JSON")
      .option("--keep", "DIR", "bake into DIR and keep the files (default: a temp folder)")
      .flag("--no-correct", "blend only (no collision correction)")
      .flag("--no-audit", "skip the per-frame audit")
      .flag("--no-resolve", "skip the penetration resolution")
      .option("--exit-fade", "K", "the resolution's exit fade (as for bake)", "0.15")
      .option("--also-exit-fade", "K",
              "bake on OpenCL a second time with this exit fade (e.g. 0, before the fade) in the "
              "same run")
      .flag("--sync", "fsync every output before its rename")
      .option("--blend", "MODE", "world (the talk: correction searches P~) or local", "local")
      .option("--weights", "MODE",
              "auto (the pose model; the database fits one), model, qp, nearest or bind", "auto")
      .option("--also-weights", "MODE",
              "bake on OpenCL a second time with these weights (e.g. qp, the 0.1 default) in the "
              "same run")
      .option("--align", "MODE", "none, rigid or rigid-all", "rigid")
      .flag("--host-staging",
            "also bake through OpenCL with every block of frames staged through host memory "
            "(each kernel call uploads its inputs and reads its outputs back: the transfers "
            "before blocks stayed on the device)")
      .flag("--no-host", "skip the host reference bake")
      .flag("--full-search",
            "also bake each path with the clearance certificate off (every closest point "
            "searched), first, and check that both bakes wrote the same files byte for byte");
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  Workload w = workload(parser.get("--workload"));
  if (parser.has("--frames")) {
    w.frames = parser.getInt("--frames", 1);
  }
  const fs::path root =
      parser.has("--keep")
          ? fs::path(parser.get("--keep"))
          : fs::temp_directory_path() / ("drivenshape-bench-" + std::to_string(::getpid()));
  fs::create_directories(root / "host");
  fs::create_directories(root / "cl");
  fs::create_directories(root / "cl-host-staging");
  fs::create_directories(root / "cl-full-search");
  fs::create_directories(root / "host-full-search");

  const ds::Mesh driver = tube(w.driverRings, w.driverSegments, 0.1f);
  const ds::Mesh driven = tube(w.drivenRings, w.drivenSegments, 0.12f);
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> angle(-1.2f, 1.2f);
  // Reference clip: 4x as many random poses as shapes; the database picks from them.
  const int referenceFrames = 4 * w.shapes;
  std::vector<float> refDriver(std::size_t(referenceFrames) * driver.vertexCount() * 3);
  std::vector<float> refDriven(std::size_t(referenceFrames) * driven.vertexCount() * 3);
  for (int f = 0; f < referenceFrames; ++f) {
    const float a = angle(rng), b = angle(rng), c = angle(rng);
    bend(driver, a, b, c, &refDriver[std::size_t(f) * driver.vertexCount() * 3]);
    bend(driven, a * 1.05f, b * 0.95f, c, &refDriven[std::size_t(f) * driven.vertexCount() * 3]);
  }
  ds::writePc2((root / "ref.driver.pc2").string(), driver.vertexCount(), 1, referenceFrames,
               refDriver.data());
  ds::writePc2((root / "ref.driven.pc2").string(), driven.vertexCount(), 1, referenceFrames,
               refDriven.data());
  std::vector<float> shot(std::size_t(w.frames) * driver.vertexCount() * 3);
  for (int f = 0; f < w.frames; ++f) {
    const float t = float(f) / 24.0f;
    bend(driver, std::sin(t), 0.8f * std::sin(0.7f * t), 0.5f * std::cos(0.3f * t),
         &shot[std::size_t(f) * driver.vertexCount() * 3]);
  }
  ds::writePc2((root / "shot.driver.pc2").string(), driver.vertexCount(), 1, w.frames, shot.data());

  const auto refDriverCache = ds::openPointCache((root / "ref.driver.pc2").string());
  const auto refDrivenCache = ds::openPointCache((root / "ref.driven.pc2").string());
  ds::DatabaseBuildOptions dbOptions;
  dbOptions.count = w.shapes;
  const ds::Database db =
      ds::buildDatabase(driver, driven, *refDriverCache, *refDrivenCache, dbOptions);
  const auto shotCache = ds::openPointCache((root / "shot.driver.pc2").string());

  ds::BakeOptions options;
  for (int f = 1; f <= w.frames; ++f) {
    options.frames.push_back(f);
  }
  options.chunkSize = parser.getInt("--batch", 1);
  options.threads = parser.getInt("--threads", 0);
  options.compression = ds::parseExrCompression(parser.get("--compression"));
  options.zipEncoder = ds::parseZipEncoder(parser.get("--zip-encoder"));
  options.evaluator.correct = !parser.has("--no-correct");
  options.evaluator.audit = !parser.has("--no-audit");
  options.evaluator.resolve = !parser.has("--no-resolve");
  options.evaluator.exitFade = parser.getDouble("--exit-fade", 0.0);
  options.syncOutputs = parser.has("--sync");
  options.evaluator.blend = ds::parseBlendMode(parser.get("--blend"), "--blend");
  options.evaluator.align = ds::parseAlignMode(parser.get("--align"), "--align");
  options.evaluator.weightMode = ds::parseWeightMode(parser.get("--weights"), "--weights");

  const std::unique_ptr<ds::Device> clDevice =
      ds::cli::openCliDevice(parser.get("--device"), std::cerr);
  const std::string clName = clDevice->description();
  std::printf(
      "workload %s: driver %d, driven %d vertices, %d shapes, %d frames, batch %d, "
      "compression %s (%s), correction %s, audit %s\n",
      w.name.c_str(), driver.vertexCount(), driven.vertexCount(), db.shapeCount(), w.frames,
      options.chunkSize, parser.get("--compression").c_str(),
      ds::zipEncoderName(options.zipEncoder), options.evaluator.correct ? "on" : "off",
      options.evaluator.audit ? "on" : "off");
  printHeader();

  nlohmann::json report{{"workload", w.name},
                        {"driver_vertices", driver.vertexCount()},
                        {"driven_vertices", driven.vertexCount()},
                        {"shapes", db.shapeCount()},
                        {"frames", w.frames},
                        {"batch", options.chunkSize},
                        {"correct", options.evaluator.correct},
                        {"audit", options.evaluator.audit}};
  // Warm-up: builds the kernels (PoCL compiles on first use) outside the timed bakes.
  {
    ds::BakeOptions warm = options;
    warm.frames = {1};
    warm.outputPattern = (root / "cl" / "warm.####.exr").string();
    ds::bake(db, *shotCache, *clDevice, warm);
  }
  const bool fullSearch = parser.has("--full-search");
  if (fullSearch) {
    report["opencl_full_search"] = bakeFullSearch(db, *shotCache, *clDevice, options,
                                                  root / "cl-full-search", "OpenCL, full search");
  }
  options.outputPattern = (root / "cl" / "shot.####.exr").string();
  resetPeakRss();
  const ds::TransferCounts before = clDevice->transfers();
  const ds::BakeResult cl = ds::bake(db, *shotCache, *clDevice, options);
  const ds::TransferCounts after = clDevice->transfers();
  const double clRss = peakRssMiB();
  printRow("OpenCL: " + clName.substr(0, 20), cl, clRss);
  report["opencl"] = timesJson(cl, clRss);
  report["opencl"]["device"] = clName;
  report["opencl"]["programs_built"] = clDevice->programsBuilt();
  report["opencl"]["transfers"] =
      transfersPerBatch("OpenCL", before, after, w.frames, options.chunkSize);
  if (parser.has("--also-weights")) {
    ds::BakeOptions other = options;
    other.evaluator.weightMode =
        ds::parseWeightMode(parser.get("--also-weights"), "--also-weights");
    other.outputPattern = (root / "cl" / "other.####.exr").string();
    const ds::BakeResult again = ds::bake(db, *shotCache, *clDevice, other);
    printRow("same, weights " + parser.get("--also-weights"), again, peakRssMiB());
    report["opencl_" + parser.get("--also-weights")] = timesJson(again, peakRssMiB());
  }
  if (parser.has("--also-exit-fade")) {
    ds::BakeOptions other = options;
    other.evaluator.exitFade = parser.getDouble("--also-exit-fade", 0.0);
    other.outputPattern = (root / "cl" / "fade.####.exr").string();
    const ds::BakeResult again = ds::bake(db, *shotCache, *clDevice, other);
    printRow("same, exit fade " + parser.get("--also-exit-fade"), again, peakRssMiB());
    report["opencl_exit_fade_" + parser.get("--also-exit-fade")] = timesJson(again, peakRssMiB());
  }
  if (fullSearch) {
    report["opencl"]["same_files_as_full_search"] =
        sameFiles(root / "cl", root / "cl-full-search", w.frames, "OpenCL");
  }
  if (parser.has("--host-staging") && clDevice->isOpenCl()) {
    ds::cli::HostStagingDevice staging(*clDevice);
    options.outputPattern = (root / "cl-host-staging" / "shot.####.exr").string();
    const ds::TransferCounts start = clDevice->transfers();
    const ds::BakeResult again = ds::bake(db, *shotCache, staging, options);
    printRow("same, staged on host", again, peakRssMiB());
    report["opencl_host_staging"] = timesJson(again, peakRssMiB());
    report["opencl_host_staging"]["transfers"] = transfersPerBatch(
        "same, staged on host", start, clDevice->transfers(), w.frames, options.chunkSize);
  }
  if (!parser.has("--no-host")) {
    const std::unique_ptr<ds::Device> host = ds::makeHostDevice();
    if (fullSearch) {
      report["host_full_search"] = bakeFullSearch(db, *shotCache, *host, options,
                                                  root / "host-full-search", "host, full search");
    }
    options.outputPattern = (root / "host" / "shot.####.exr").string();
    resetPeakRss();
    const ds::BakeResult hr = ds::bake(db, *shotCache, *host, options);
    const double hostRss = peakRssMiB();
    printRow("host reference", hr, hostRss);
    report["host"] = timesJson(hr, hostRss);
    if (fullSearch) {
      report["host"]["same_files_as_full_search"] =
          sameFiles(root / "host", root / "host-full-search", w.frames, "host");
    }
    std::printf("OpenCL / host speed-up: whole bake %.2fx, project %.2fx, blend %.2fx\n",
                hr.times.total / cl.times.total,
                hr.times.stage("project") / cl.times.stage("project"),
                hr.times.stage("blend") / cl.times.stage("blend"));
  }
  if (parser.has("--json")) {
    std::ofstream(parser.get("--json")) << drivenshape::jsonText(report, 1) << "\n";
  }
  if (!parser.has("--keep")) {
    fs::remove_all(root);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return drivenshape::cli::runMain("drivenshape_bench", argc, argv, runBench);
}
