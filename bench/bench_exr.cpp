// SPDX-License-Identifier: Apache-2.0
// drivenshape_bench_exr: what each way of writing our EXRs costs (issue 18). Writes the same
// frames with every codec OpenEXR 3.1 offers (and with drivenshape's libdeflate ZIP writer),
// reads them back with OpenEXR and with oiiotool, and prints one table: bytes per frame, write
// and read milliseconds per frame, the largest position error. A benchmark, not a test: it
// asserts nothing but that lossless files decode to the written bits.
//
//   drivenshape_bench_exr [--frames N] [--repeats R] [--pants DIR] [--posmap-res 2048]
//                         [--data W1,W2,pants,posmap] [--out DIR]
//
// Data sets: W1 and W2 are frames of the synthetic driven tube of drivenshape_bench (5,000 and
// 200,000 vertices, 1 m long); `pants` the test_public.driven.pc2 frames of --pants DIR (4,581
// vertices); `posmap` 2048 x 2048 position maps (R G B A) of the pants mesh driven_rest.obj.
// Every option writes the same pixels under the same header (the one drivenshape writes, with
// channel types and compression changed), so the rows differ only in the encoding.

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfThreading.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <Imath/half.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/position_map.h>
#include <drivenshape/position_map_backend.h>
#include <drivenshape/position_map_tables.h>

#include "cli_args.h"
#include "exr_zip_writer.h"
#include "run_main.h"
#include "synthetic_workload.h"

namespace ds = drivenshape;
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// CPU time of the calling thread in ms: what one-thread figures report, so that other jobs on
/// a shared machine do not inflate them (wall time does).
double threadCpuMs() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) * 1e3 + static_cast<double>(now.tv_nsec) * 1e-6;
}

/// User + system CPU time of the finished child processes, in ms.
double childrenCpuMs() {
  rusage usage{};
  getrusage(RUSAGE_CHILDREN, &usage);
  return (static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec)) * 1e3 +
         (static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec)) * 1e-3;
}

/// One data set: frames of W x H pixels, channels (alphabetical, as in the file) that are x, y,
/// z of the position or the coverage A; the header drivenshape writes for it.
struct DataSet {
  std::string name;
  std::string size;  // for the table: vertices or texels
  int width = 0;
  int height = 0;
  std::vector<std::string> channels;          // file order
  std::vector<int> axis;                      // per channel: 0..2 position axis, -1 coverage
  std::vector<std::vector<float>> positions;  // per frame: W*H*3 interleaved
  std::vector<float> coverage;                // W*H
  Imf::Header header{1, 1};
};

/// The header of the file drivenshape itself writes (read back), the template of every option.
Imf::Header headerOf(const std::string& path) {
  Imf::InputFile file(path.c_str());
  return file.header();
}

/// A point-cache data set from F frames of V vertices (frame-major xyz).
DataSet pointCacheData(const std::string& name, int vertexCount, std::vector<float> frames,
                       int frameCount, const fs::path& scratch) {
  DataSet data;
  data.name = name;
  data.size = std::to_string(vertexCount) + " vertices";
  data.width = 1024;
  data.height = (vertexCount + data.width - 1) / data.width;
  data.channels = {"A", "P.X", "P.Y", "P.Z"};
  data.axis = {-1, 0, 1, 2};
  const std::size_t pixels = static_cast<std::size_t>(data.width) * data.height;
  data.coverage.assign(pixels, 0.0f);
  std::fill(data.coverage.begin(), data.coverage.begin() + vertexCount, 1.0f);
  for (int f = 0; f < frameCount; ++f) {
    std::vector<float> padded(pixels * 3, 0.0f);
    const float* xyz = frames.data() + static_cast<std::size_t>(f) * vertexCount * 3;
    std::copy(xyz, xyz + static_cast<std::size_t>(vertexCount) * 3, padded.begin());
    data.positions.push_back(std::move(padded));
  }
  const std::string probe = (scratch / (name + ".header.exr")).string();
  ds::ExrWriteOptions options;
  options.syncToDisk = false;
  options.topologyHash = 0x0123456789abcdefull;
  options.settingsHash = 0x0123456789abcdefull;
  ds::writePointCacheExr(probe, vertexCount, frames.data(), nullptr, options);
  data.header = headerOf(probe);
  return data;
}

DataSet tubeData(const std::string& name, int frameCount, const fs::path& scratch) {
  const ds::bench::Workload w = ds::bench::workload(name);
  const ds::Mesh driven = ds::bench::tube(w.drivenRings, w.drivenSegments, 0.12f);
  const int v = driven.vertexCount();
  std::vector<float> frames(static_cast<std::size_t>(frameCount) * v * 3);
  for (int f = 0; f < frameCount; ++f) {  // the sweep of drivenshape_bench's shot
    const float t = float(f + 1) / 24.0f;
    ds::bench::bend(driven, std::sin(t), 0.8f * std::sin(0.7f * t), 0.5f * std::cos(0.3f * t),
                    &frames[static_cast<std::size_t>(f) * v * 3]);
  }
  return pointCacheData(name, v, std::move(frames), frameCount, scratch);
}

std::vector<int> firstFrames(const ds::PointCacheReader& cache, int count) {
  std::vector<int> frames = cache.frames();
  frames.resize(std::min<std::size_t>(frames.size(), static_cast<std::size_t>(count)));
  return frames;
}

DataSet pantsData(const std::string& dir, int frameCount, const fs::path& scratch) {
  const auto cache = ds::openPointCache(dir + "/test_public.driven.pc2");
  const std::vector<int> frames = firstFrames(*cache, frameCount);
  return pointCacheData("pants", cache->vertexCount(), ds::readFrames(*cache, frames),
                        static_cast<int>(frames.size()), scratch);
}

DataSet posmapData(const std::string& dir, int resolution, int frameCount,
                   const fs::path& scratch) {
  const ds::Mesh mesh = ds::readObj(dir + "/driven_rest.obj");
  const auto cache = ds::openPointCache(dir + "/test_public.driven.pc2");
  const std::vector<int> frames = firstFrames(*cache, frameCount);
  const std::vector<float> xyz = ds::readFrames(*cache, frames);
  const ds::PositionMapTables tables =
      ds::buildPositionMapTables(mesh, resolution, resolution, 8, "driven_rest.obj");
  auto backend = ds::makeHostPositionMaps();
  backend->upload(tables);
  DataSet data;
  data.name = "posmap";
  data.size = std::to_string(resolution) + "^2 texels";
  data.width = data.height = resolution;
  data.channels = {"A", "B", "G", "R"};
  data.axis = {-1, 2, 1, 0};
  data.coverage = tables.coverage;
  const std::size_t texels = tables.texelCount();
  for (std::size_t f = 0; f < frames.size(); ++f) {
    std::vector<float> positions(texels * 3);
    backend->evaluate(1, xyz.data() + f * 3 * static_cast<std::size_t>(mesh.vertexCount()),
                      positions.data(), nullptr);
    data.positions.push_back(std::move(positions));
  }
  const std::string probe = (scratch / "posmap.header.exr").string();
  ds::PositionMapFrameHeader header;
  header.meshVertexCount = mesh.vertexCount();
  header.topologyHash = tables.topologyHash;
  ds::writePositionMapExr(probe, resolution, resolution, data.positions[0].data(),
                          data.coverage.data(), nullptr, header);
  data.header = headerOf(probe);
  return data;
}

/// One way of writing a frame.
struct Option {
  std::string name;
  enum Kind { kOpenExr, kChunked } kind = kOpenExr;
  Imf::Compression compression = Imf::ZIP_COMPRESSION;
  int level = 0;       // deflate level; 0: OpenEXR's default
  bool halfP = false;  // position channels as HALF
  bool lossy = false;
  ds::exr_detail::Deflater deflater = ds::exr_detail::Deflater::kLibdeflate;
};

/// The frame's pixels as the option stores them: float planes, or half for halfP.
struct Planes {
  std::vector<std::vector<float>> floats;
  std::vector<std::vector<half>> halves;
};

Planes planesOf(const DataSet& data, const std::vector<float>& positions, bool halfP) {
  const std::size_t pixels = data.coverage.size();
  Planes planes;
  for (std::size_t c = 0; c < data.channels.size(); ++c) {
    std::vector<float> plane(pixels);
    for (std::size_t i = 0; i < pixels; ++i) {
      plane[i] = data.axis[c] < 0 ? data.coverage[i] : positions[3 * i + data.axis[c]];
    }
    if (halfP && data.axis[c] >= 0) {
      planes.halves.emplace_back(plane.begin(), plane.end());
      planes.floats.emplace_back();
    } else {
      planes.halves.emplace_back();
      planes.floats.push_back(std::move(plane));
    }
  }
  return planes;
}

void writeFrame(const DataSet& data, const Option& option, const Planes& planes,
                const std::string& path, int threads) {
  Imf::Header header = data.header;
  header.compression() = option.compression;
  if (option.level > 0) {
    header.zipCompressionLevel() = option.level;
  }
  Imf::FrameBuffer frameBuffer;
  const std::size_t width = static_cast<std::size_t>(data.width);
  for (std::size_t c = 0; c < data.channels.size(); ++c) {
    const bool half = !planes.halves[c].empty();
    header.channels()[data.channels[c]].type = half ? Imf::HALF : Imf::FLOAT;
    char* base = half ? reinterpret_cast<char*>(const_cast<::half*>(planes.halves[c].data()))
                      : reinterpret_cast<char*>(const_cast<float*>(planes.floats[c].data()));
    const std::size_t bytes = half ? 2 : 4;
    frameBuffer.insert(data.channels[c],
                       Imf::Slice(half ? Imf::HALF : Imf::FLOAT, base, bytes, bytes * width));
  }
  if (option.kind == Option::kChunked) {
    ds::exr_detail::ZipEncoding encoding;
    encoding.deflater = option.deflater;
    encoding.level = option.level;
    encoding.threads = threads;
    std::ofstream file(path, std::ios::binary);
    ds::exr_detail::writeZipExr(file, header, frameBuffer, encoding);
  } else {
    Imf::OutputFile file(path.c_str(), header, threads);
    file.setFrameBuffer(frameBuffer);
    file.writePixels(data.height);
  }
}

/// Reads every channel as float with OpenEXR; returns the planes (file order).
std::vector<std::vector<float>> readAll(const DataSet& data, const std::string& path) {
  Imf::InputFile file(path.c_str(), 1);
  Imf::FrameBuffer frameBuffer;
  const std::size_t width = static_cast<std::size_t>(data.width);
  std::vector<std::vector<float>> planes(data.channels.size(),
                                         std::vector<float>(data.coverage.size()));
  for (std::size_t c = 0; c < data.channels.size(); ++c) {
    frameBuffer.insert(data.channels[c],
                       Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(planes[c].data()),
                                  sizeof(float), sizeof(float) * width));
  }
  file.setFrameBuffer(frameBuffer);
  file.readPixels(0, data.height - 1);
  return planes;
}

/// Runs `command`; its CPU time (user + system) in ms and its output.
double timeCommand(const std::string& command, std::string& output) {
  const double start = childrenCpuMs();
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) {
    DS_THROW(kInternal, "cannot run ", command);
  }
  char buffer[4096];
  output.clear();
  while (std::fgets(buffer, sizeof(buffer), pipe) != nullptr) {
    output += buffer;
  }
  if (pclose(pipe) != 0) {
    DS_THROW(kInternal, command, " failed:\n", output);
  }
  return childrenCpuMs() - start;
}

/// `oiiotool --info --hash` of the files (one process, one thread): SHA-1 of each file's
/// pixels, and the CPU ms per decoded file. The files are listed `passes` times in one process
/// and a run with one file is subtracted, which cancels the process start-up (about 0.4 s).
double oiiotoolDecode(const std::vector<std::string>& files, int passes,
                      std::vector<std::string>& hashes) {
  std::string all = "oiiotool --threads 1 --info --hash";
  for (int pass = 0; pass < passes; ++pass) {
    for (const std::string& file : files) {
      all += " '" + file + "'";
    }
  }
  std::string output;
  const double one = timeCommand("oiiotool --threads 1 --info --hash '" + files[0] + "'", output);
  const double many = timeCommand(all, output);
  std::istringstream lines(output);
  std::string line;
  hashes.clear();
  while (std::getline(lines, line)) {
    const auto at = line.find("SHA-1: ");
    if (at != std::string::npos) {
      hashes.push_back(line.substr(at + 7));
    }
  }
  const std::size_t decoded = files.size() * static_cast<std::size_t>(passes);
  if (hashes.size() != decoded) {
    DS_THROW(kInternal, "oiiotool printed ", hashes.size(), " hashes for ", decoded, " files:\n",
             output);
  }
  hashes.resize(files.size());
  return (many - one) / static_cast<double>(decoded - 1);
}

std::vector<Option> options() {
  using ds::exr_detail::Deflater;
  std::vector<Option> list;
  auto stock = [&](const std::string& name, Imf::Compression c, int level = 0) {
    Option o;
    o.name = name;
    o.compression = c;
    o.level = level;
    list.push_back(o);
    return &list.back();
  };
  auto chunked = [&](const std::string& name, Imf::Compression c, Deflater d, int level) {
    Option o;
    o.name = name;
    o.kind = Option::kChunked;
    o.compression = c;
    o.deflater = d;
    o.level = level;
    list.push_back(o);
  };
  stock("none", Imf::NO_COMPRESSION);
  stock("rle", Imf::RLE_COMPRESSION);
  stock("zip (OpenEXR, zlib 4)", Imf::ZIP_COMPRESSION);  // 4: OpenEXR 3.1's default level
  stock("zip (OpenEXR, zlib 1)", Imf::ZIP_COMPRESSION, 1);
  stock("zips (OpenEXR, zlib 4)", Imf::ZIPS_COMPRESSION);
  stock("piz", Imf::PIZ_COMPRESSION);
  stock("b44 (float)", Imf::B44_COMPRESSION)->lossy = true;
  stock("dwaa (float)", Imf::DWAA_COMPRESSION)->lossy = true;
  // The same bytes as "zip (OpenEXR, zlib 4)": what the chunk writer itself costs.
  chunked("zip, ours, zlib 4", Imf::ZIP_COMPRESSION, Deflater::kZlib, 4);
  chunked("zip, libdeflate 1", Imf::ZIP_COMPRESSION, Deflater::kLibdeflate, 1);
  chunked("zip, libdeflate 4", Imf::ZIP_COMPRESSION, Deflater::kLibdeflate, 4);
  chunked("zip, libdeflate 6", Imf::ZIP_COMPRESSION, Deflater::kLibdeflate, 6);
  chunked("zips, libdeflate 1", Imf::ZIPS_COMPRESSION, Deflater::kLibdeflate, 1);
  for (auto [name, c] :
       {std::pair<const char*, Imf::Compression>{"half P, zip", Imf::ZIP_COMPRESSION},
        {"half P, b44", Imf::B44_COMPRESSION},
        {"half P, dwaa", Imf::DWAA_COMPRESSION}}) {
    Option* o = stock(name, c);
    o->halfP = true;
    o->lossy = true;
  }
  return list;
}

ds::cli::ArgParser benchParser() {
  ds::cli::ArgParser parser(
      "drivenshape_bench_exr [options]",
      "Writes the same frames with every EXR encoding worth considering and prints one table: "
      "bytes, write and read ms per frame, largest position error.");
  parser.option("--data", "LIST", "data sets: W1, W2, pants, posmap", "W1,W2,pants,posmap")
      .option("--pants", "DIR",
              "folder of the pants data (test_public.driven.pc2, "
              "driven_rest.obj); needed for pants and posmap")
      .option("--frames", "N", "frames per option (W1, pants; W2 and posmap take N/4, N/16)", "48")
      .option("--posmap-res", "N", "position map side in texels", "2048")
      .option("--repeats", "R", "write each option's frames R times; the fastest pass counts", "3")
      .option("--only", "TEXT", "only the options whose name contains TEXT (e.g. libdeflate)")
      .option("--out", "DIR", "scratch folder (default: a temp folder, removed)");
  return parser;
}

void printTableHead(unsigned cores) {
  std::printf(
      "EXR encodings, %u cores. ms per frame: write on 1 thread (CPU time; %uT gain: wall time "
      "on 1 thread / on all, with OpenEXR's thread pool or our chunk threads; '-' where a frame "
      "is one chunk); read with "
      "OpenEXR (drivenshape's reader; all channels as float for posmap) and with oiiotool "
      "--threads 1 --info --hash (CPU time, start-up excluded). Error: largest |read - written| "
      "of a position over covered pixels (metres)\n",
      cores, cores);
  const std::string manyThreads = std::to_string(cores) + "T gain";
  std::printf("%-7s %-17s %-24s %11s %6s %8s %8s %8s %9s %10s %5s\n", "data", "size", "option",
              "bytes/frame", "ratio", "write 1T", manyThreads.c_str(), "read", "oiiotool",
              "max error", "bits");
}

/// Data set `name` of --data: W2 takes a quarter of --frames, posmap a sixteenth.
DataSet loadDataSet(const std::string& name, const ds::cli::ArgParser& parser, int frames,
                    const fs::path& root) {
  if (name == "W1") {
    return tubeData("W1", frames, root);
  }
  if (name == "W2") {
    return tubeData("W2", std::max(2, frames / 4), root);
  }
  if (name == "pants" || name == "posmap") {
    if (!parser.has("--pants")) {
      DS_THROW(kUsage, "data set ", name, " needs --pants DIR");
    }
    return name == "pants" ? pantsData(parser.get("--pants"), frames, root)
                           : posmapData(parser.get("--pants"), parser.getInt("--posmap-res", 1),
                                        std::max(2, frames / 16), root);
  }
  DS_THROW(kUsage, "unknown data set '", name, "' (W1, W2, pants, posmap)");
}

/// One row of the table: an option on a data set.
struct Row {
  double bytes = 0;  // per frame
  double write1 = 1e30, wall1 = 1e30, wallMany = 1e30;
  double read = 1e30;
  double maxError = 0;
  bool bitwise = true;
  double oiio = 0;
  std::vector<std::string> hashes;
};

/// Write times: the best of `repeats` passes; one and all threads take turns, so that both see
/// the same load of a shared machine and their ratio holds where the wall times do not. Then
/// the files checked afterwards, written on one thread.
void timeWrites(const DataSet& data, const Option& option, const std::vector<Planes>& planes,
                const std::vector<std::string>& files, int repeats, unsigned cores, Row& row) {
  const int count = static_cast<int>(files.size());
  const bool oneChunk = data.height <= 16;
  // All frames once on `threads` threads: {CPU ms of this thread, wall ms} per frame.
  auto writeAll = [&](int threads) {
    Imf::setGlobalThreadCount(threads > 1 ? threads : 0);
    const auto start = Clock::now();
    const double cpu = threadCpuMs();
    for (int f = 0; f < count; ++f) {
      writeFrame(data, option, planes[f], files[f], threads);
    }
    const std::pair<double, double> ms{(threadCpuMs() - cpu) / count, msSince(start) / count};
    Imf::setGlobalThreadCount(0);
    return ms;
  };
  for (int r = 0; r < repeats; ++r) {
    const auto [cpu, wall] = writeAll(1);
    row.write1 = std::min(row.write1, cpu);
    row.wall1 = std::min(row.wall1, wall);
    if (!oneChunk) {
      row.wallMany = std::min(row.wallMany, writeAll(static_cast<int>(cores)).second);
    }
  }
  writeAll(1);
}

/// Read back: the best of `repeats` timed passes, then the bits and the position error.
void readBack(const std::string& name, const DataSet& data, const std::vector<std::string>& files,
              int repeats, Row& row) {
  const int count = static_cast<int>(files.size());
  for (int r = 0; r < repeats; ++r) {
    const double start = threadCpuMs();
    for (int f = 0; f < count; ++f) {
      if (name == "posmap") {
        readAll(data, files[f]);
      } else {
        std::vector<float> xyz;
        ds::readPointCacheExr(files[f], xyz);
      }
    }
    row.read = std::min(row.read, (threadCpuMs() - start) / count);
  }
  for (int f = 0; f < count; ++f) {
    const auto planesRead = readAll(data, files[f]);
    for (std::size_t c = 0; c < data.channels.size(); ++c) {
      for (std::size_t i = 0; i < data.coverage.size(); ++i) {
        const float want =
            data.axis[c] < 0 ? data.coverage[i] : data.positions[f][3 * i + data.axis[c]];
        const float got = planesRead[c][i];
        row.bitwise = row.bitwise && std::memcmp(&want, &got, sizeof(float)) == 0;
        if (data.axis[c] >= 0 && data.coverage[i] > 0.0f) {
          row.maxError = std::max(row.maxError, static_cast<double>(std::fabs(got - want)));
        }
      }
    }
  }
}

/// Writes, reads and decodes data set `name` with `option`; "none" sets `rawBytes` and the
/// `referenceHashes` the lossless options must match.
Row measureOption(const std::string& name, const DataSet& data, const Option& option, int repeats,
                  unsigned cores, const fs::path& root, double& rawBytes,
                  std::vector<std::string>& referenceHashes) {
  const int count = static_cast<int>(data.positions.size());
  std::vector<Planes> planes;
  for (const auto& positions : data.positions) {
    planes.push_back(planesOf(data, positions, option.halfP));
  }
  std::vector<std::string> files;
  for (int f = 0; f < count; ++f) {
    files.push_back((root / (name + "." + std::to_string(f) + ".exr")).string());
  }
  Row row;
  timeWrites(data, option, planes, files, repeats, cores, row);
  for (const std::string& file : files) {
    row.bytes += static_cast<double>(fs::file_size(file));
  }
  row.bytes /= count;
  if (option.compression == Imf::NO_COMPRESSION) {
    rawBytes = row.bytes;
  }
  readBack(name, data, files, repeats, row);
  const int passes = std::max(2, (name == "posmap" ? 8 : 96) / count);
  row.oiio = oiiotoolDecode(files, passes, row.hashes);
  if (option.compression == Imf::NO_COMPRESSION) {
    referenceHashes = row.hashes;
  }
  return row;
}

int runBench(const std::vector<std::string>& args) {
  ds::cli::ArgParser parser = benchParser();
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const int frames = parser.getInt("--frames", 2);
  const int repeats = parser.getInt("--repeats", 1);
  const fs::path root =
      parser.has("--out")
          ? fs::path(parser.get("--out"))
          : fs::temp_directory_path() / ("drivenshape-bench-exr-" + std::to_string(::getpid()));
  fs::create_directories(root);
  std::vector<std::string> wanted;
  std::istringstream list(parser.get("--data"));
  for (std::string name; std::getline(list, name, ',');) {
    wanted.push_back(name);
  }
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  printTableHead(cores);
  for (const std::string& name : wanted) {
    const DataSet data = loadDataSet(name, parser, frames, root);
    double rawBytes = 0;
    std::vector<std::string> referenceHashes;
    for (const Option& option : options()) {
      if (parser.has("--only") && option.compression != Imf::NO_COMPRESSION &&
          option.name.find(parser.get("--only")) == std::string::npos) {
        continue;  // "none" always runs: it is the reference of the ratio and the hashes
      }
      const Row row =
          measureOption(name, data, option, repeats, cores, root, rawBytes, referenceHashes);
      const bool sameHashes = row.hashes == referenceHashes;
      if (!option.lossy && (!row.bitwise || !sameHashes)) {
        DS_THROW(kInternal, name, " ", option.name, ": a lossless option did not read back ",
                 row.bitwise ? "the same under oiiotool" : "bitwise");
      }
      char many[16] = "-";
      if (data.height > 16) {
        std::snprintf(many, sizeof(many), "%.2fx", row.wall1 / row.wallMany);
      }
      std::printf("%-7s %-17s %-24s %11.0f %6.2f %8.2f %8s %8.2f %9.2f %10.2g %5s\n", name.c_str(),
                  data.size.c_str(), option.name.c_str(), row.bytes, rawBytes / row.bytes,
                  row.write1, many, row.read, row.oiio, row.maxError,
                  row.bitwise ? "same" : (sameHashes ? "hash=" : "lossy"));
      std::fflush(stdout);
    }
  }
  if (!parser.has("--out")) {
    fs::remove_all(root);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return drivenshape::cli::runMain("drivenshape_bench_exr", argc, argv, runBench);
}
