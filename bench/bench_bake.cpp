// SPDX-License-Identifier: Apache-2.0
// drivenshape_bench: bakes a synthetic shot of the workloads of docs/performance.md (W1, W2)
// through OpenCL and through the host reference in one run, and reports per-stage times and frames
// per second. A benchmark, not a test: it asserts nothing, it measures.
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
#include <drivenshape/database_build.h>
#include <drivenshape/error.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/settings_table.h>

#include "json_text.h"

#include "bench_floor.h"
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
const char* const kStages[] = {"align",  "project", "weights", "blend",  "correct",
                               "strain", "resolve", "settle",  "layers", "audit"};

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
  std::printf("%-24s %6s %6s %6s %6s %6s %7s %6s %7s %6s %6s %6s %6s %6s %6s %8s %9s %7s %8s\n",
              "path (s per stage)", "read", "align", "proj", "QP", "blend", "correct", "strain",
              "resolve", "settle", "layers", "audit", "write", "wait", "setup", "total", "frames/s",
              "RSS MiB", "cleared");
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
      "%-24s %6.3f %6.3f %6.3f %6.3f %6.3f %7.3f %6.3f %7.3f %6.3f %6.3f %6.3f %6.3f %6.3f "
      "%6.3f %8.3f %9.1f %7.0f %8s\n",
      name.substr(0, 24).c_str(), r.times.read, r.times.stage("align"), r.times.stage("project"),
      r.times.stage("weights"), r.times.stage("blend"), r.times.stage("correct"),
      r.times.stage("strain"), r.times.stage("resolve"), r.times.stage("settle"),
      r.times.stage("layers"), r.times.stage("audit"), r.times.write,
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

void declareOptions(ds::cli::ArgParser& parser) {
  parser.option("--workload", "W", "W1 (5k/5k vertices, 30 shapes, 1000 frames) or W2", "W1")
      .option("--frames", "N", "override the workload's frame count")
      .option("--device", "SPEC", "OpenCL device (as for bake)", "auto")
      .option("--json", "PATH", "also write the figures as JSON")
      .option("--keep", "DIR", "bake into DIR and keep the files (default: a temp folder)")
      .settings()
      .repeated("--also", "KEY=VALUE", 1,
                "bake on OpenCL a second time with this setting changed (a key of the settings "
                "table, as the bake's options above spell it: weight_mode=qp) in the same run")
      .flag("--sync", "fsync every output before its rename")
      .flag("--host-staging",
            "also bake through OpenCL with every block of frames staged through host memory "
            "(each kernel call uploads its inputs and reads its outputs back: the transfers "
            "before blocks stayed on the device)")
      .flag("--no-host", "skip the host reference bake")
      .flag("--full-search",
            "also bake each path with the clearance certificate off (every closest point "
            "searched), first, and check that both bakes wrote the same files byte for byte")
      .flag("--floor",
            "last, time the resolution's closest-point search on the shot's cloth three ways, "
            "block by block: the full search, the clearance certificate, and a run told in "
            "advance which points need a search (the floor)");
}

/// Writes the reference clip and the shot of `w` (a bending tube in a looser one) under
/// `root` (ref.*.pc2, shot.driver.pc2) and builds the database of the reference clip.
ds::Database makeWorkload(const Workload& w, const fs::path& root) {
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
  return ds::buildDatabase(driver, driven, *refDriverCache, *refDrivenCache, dbOptions);
}

/// What every bake of the run shares: the database, the shot, the device, the options and the
/// JSON report the bakes add to.
struct Bench {
  const ds::Database& db;
  const ds::PointCacheReader& shot;
  ds::Device& device;
  ds::BakeOptions options;
  fs::path root;
  int frames = 0;
  nlohmann::json report;
};

/// The OpenCL bake, then one per --also KEY=VALUE, into the report.
ds::BakeResult bakeOpenCl(const ds::cli::ArgParser& parser, Bench& bench) {
  bench.options.outputPattern = (bench.root / "cl" / "shot.####.exr").string();
  resetPeakRss();
  const ds::TransferCounts before = bench.device.transfers();
  const ds::BakeResult cl = ds::bake(bench.db, bench.shot, bench.device, bench.options);
  const ds::TransferCounts after = bench.device.transfers();
  const double clRss = peakRssMiB();
  const std::string name = bench.device.description();
  printRow("OpenCL: " + name.substr(0, 20), cl, clRss);
  nlohmann::json& json = bench.report["opencl"] = timesJson(cl, clRss);
  json["device"] = name;
  json["programs_built"] = bench.device.programsBuilt();
  json["transfers"] =
      transfersPerBatch("OpenCL", before, after, bench.frames, bench.options.batchFrames);
  for (const std::vector<std::string>& also : parser.all("--also")) {
    const std::size_t equals = also.front().find('=');
    if (equals == std::string::npos) {
      DS_THROW(kUsage, "--also takes KEY=VALUE (e.g. weight_mode=qp), not '", also.front(), "'");
    }
    const ds::Setting& setting = ds::findSetting(also.front().substr(0, equals));
    const std::string text = also.front().substr(equals + 1);
    ds::BakeOptions other = bench.options;
    ds::setSetting(setting, other, ds::parseSettingValue(setting, text));
    other.outputPattern = (bench.root / "cl" / "other.####.exr").string();
    const ds::BakeResult again = ds::bake(bench.db, bench.shot, bench.device, other);
    printRow("same, " + also.front(), again, peakRssMiB());
    bench.report["opencl_" + std::string(setting.key) + "_" + text] =
        timesJson(again, peakRssMiB());
  }
  return cl;
}

/// The OpenCL device with every block staged through host memory, into the report.
void bakeHostStaged(Bench& bench) {
  ds::bench::HostStagingDevice staging(bench.device);
  ds::BakeOptions options = bench.options;
  options.outputPattern = (bench.root / "cl-host-staging" / "shot.####.exr").string();
  const ds::TransferCounts start = bench.device.transfers();
  const ds::BakeResult again = ds::bake(bench.db, bench.shot, staging, options);
  printRow("same, staged on host", again, peakRssMiB());
  bench.report["opencl_host_staging"] = timesJson(again, peakRssMiB());
  bench.report["opencl_host_staging"]["transfers"] = transfersPerBatch(
      "same, staged on host", start, bench.device.transfers(), bench.frames, options.batchFrames);
}

/// The host reference bake (and its full search), into the report; prints the speed-ups.
void bakeHost(Bench& bench, const ds::BakeResult& cl, bool fullSearch) {
  const std::unique_ptr<ds::Device> host = ds::makeHostDevice();
  ds::BakeOptions options = bench.options;
  if (fullSearch) {
    bench.report["host_full_search"] = bakeFullSearch(
        bench.db, bench.shot, *host, options, bench.root / "host-full-search", "host, full search");
  }
  options.outputPattern = (bench.root / "host" / "shot.####.exr").string();
  resetPeakRss();
  const ds::BakeResult hr = ds::bake(bench.db, bench.shot, *host, options);
  const double hostRss = peakRssMiB();
  printRow("host reference", hr, hostRss);
  bench.report["host"] = timesJson(hr, hostRss);
  if (fullSearch) {
    bench.report["host"]["same_files_as_full_search"] =
        sameFiles(bench.root / "host", bench.root / "host-full-search", bench.frames, "host");
  }
  std::printf("OpenCL / host speed-up: whole bake %.2fx, project %.2fx, blend %.2fx\n",
              hr.times.total / cl.times.total,
              hr.times.stage("project") / cl.times.stage("project"),
              hr.times.stage("blend") / cl.times.stage("blend"));
}

/// Every bake of the run, in order: warm-up, [full search], OpenCL, [--also], [host staging],
/// [host reference].
void runBakes(const ds::cli::ArgParser& parser, Bench& bench) {
  {
    // Warm-up: builds the kernels (PoCL compiles on first use) outside the timed bakes.
    ds::BakeOptions warm = bench.options;
    warm.frames = {1};
    warm.outputPattern = (bench.root / "cl" / "warm.####.exr").string();
    ds::bake(bench.db, bench.shot, bench.device, warm);
  }
  const bool fullSearch = parser.has("--full-search");
  if (fullSearch) {
    bench.report["opencl_full_search"] =
        bakeFullSearch(bench.db, bench.shot, bench.device, bench.options,
                       bench.root / "cl-full-search", "OpenCL, full search");
  }
  const ds::BakeResult cl = bakeOpenCl(parser, bench);
  if (fullSearch) {
    bench.report["opencl"]["same_files_as_full_search"] =
        sameFiles(bench.root / "cl", bench.root / "cl-full-search", bench.frames, "OpenCL");
  }
  if (parser.has("--host-staging") && bench.device.isOpenCl()) {
    bakeHostStaged(bench);
  }
  if (!parser.has("--no-host")) {
    bakeHost(bench, cl, fullSearch);
  }
  if (parser.has("--floor")) {
    bench.report["resolution_floor"] = ds::bench::measureResolutionFloor(
        bench.db, bench.shot, bench.device, bench.options, bench.root / "floor");
  }
}

int runBench(const std::vector<std::string>& args) {
  ds::cli::ArgParser parser("drivenshape_bench [options]",
                            "Bakes a synthetic workload through OpenCL and the host reference in "
                            "one run; prints per-stage seconds and frames/s.");
  declareOptions(parser);
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
  for (const char* folder :
       {"host", "cl", "cl-host-staging", "cl-full-search", "host-full-search", "floor"}) {
    fs::create_directories(root / folder);
  }
  const ds::Database db = makeWorkload(w, root);
  const auto shotCache = ds::openPointCache((root / "shot.driver.pc2").string());
  const std::unique_ptr<ds::Device> clDevice =
      ds::cli::openCliDevice(parser.get("--device"), std::cerr);
  Bench bench{db, *shotCache, *clDevice, ds::BakeOptions(), root, w.frames, nlohmann::json()};
  ds::BakeOptions& options = bench.options;
  for (int f = 1; f <= w.frames; ++f) {
    options.frames.push_back(f);
  }
  ds::cli::readSettings(parser, options);
  options.syncOutputs = parser.has("--sync");
  std::printf(
      "workload %s: driver %d, driven %d vertices, %d shapes, %d frames, batch %d, "
      "compression %s (%s), correction %s, audit %s\n",
      w.name.c_str(), db.driverVertexCount(), db.drivenVertexCount(), db.shapeCount(), w.frames,
      options.batchFrames, ds::exrCompressionName(options.compression),
      ds::zipEncoderName(options.zipEncoder), options.evaluator.correct ? "on" : "off",
      options.evaluator.audit ? "on" : "off");
  printHeader();
  bench.report = {{"workload", w.name},
                  {"driver_vertices", db.driverVertexCount()},
                  {"driven_vertices", db.drivenVertexCount()},
                  {"shapes", db.shapeCount()},
                  {"frames", w.frames},
                  {"batch", options.batchFrames},
                  {"correct", options.evaluator.correct},
                  {"audit", options.evaluator.audit}};
  runBakes(parser, bench);
  if (parser.has("--json")) {
    std::ofstream(parser.get("--json")) << drivenshape::jsonText(bench.report, 1) << "\n";
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
