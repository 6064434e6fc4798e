// SPDX-License-Identifier: Apache-2.0
#include "commands.h"

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>
#include <tuple>

#include <drivenshape/bake.h>
#include <drivenshape/binding.h>
#include <drivenshape/database.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluate.h>
#include <drivenshape/frames.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/position_map.h>
#include <drivenshape/position_map_sequence.h>
#include <drivenshape/settings_table.h>

#include "atomic_file.h"
#include "hash.h"
#include "parallel.h"
#include "progress.h"

#include "cli_args.h"
#include "device_choice.h"
#include "layer_args.h"

namespace drivenshape::cli {
namespace {

bool endsWith(const std::string& text, const std::string& suffix) {
  if (text.size() < suffix.size()) {
    return false;
  }
  return std::equal(suffix.rbegin(), suffix.rend(), text.rbegin(),
                    [](char a, char b) { return std::tolower(a) == std::tolower(b); });
}

/// out/cloth.####.exr -> out/cloth.report.json
std::string defaultReportPath(const std::string& pattern) {
  return (std::filesystem::path(pattern).parent_path() / (sequenceStem(pattern) + ".report.json"))
      .string();
}

void printMesh(const char* role, const Mesh& mesh) {
  std::cout << role << ": " << mesh.vertexCount() << " vertices, " << mesh.faceCount() << " faces, "
            << mesh.triangleCount() << " triangles, " << mesh.uvs.size() << " uvs, topology "
            << hashToHex(topologyHash(mesh)) << "\n";
  std::cout << "  groups:";
  for (const auto& name : mesh.groupNames) {
    std::cout << " " << name;
  }
  std::cout << "\n";
}

void infoDatabase(const std::string& path) {
  const Database db = loadDatabase(path);
  std::cout << "database " << path << "\n"
            << "  format version " << Database::kFormatVersion << ", written by drivenshape "
            << db.toolVersion << " at " << db.created << "\n"
            << "  content hash " << hashToHex(db.contentHash()) << "\n"
            << "  " << db.shapeCount() << " shapes (asked for " << db.options.count << ")\n";
  printMesh("  driver", db.driverMesh);
  printMesh("  driven", db.drivenMesh);
  std::cout << "  sources: driver " << db.driverSource << ", driven " << db.drivenSource << "\n"
            << "  settings: candidate frames "
            << (db.options.frames.empty() ? std::string("all")
                                          : formatFrameRange(db.options.frames))
            << ", added "
            << (db.options.addFrames.empty() ? "none" : formatFrameRange(db.options.addFrames))
            << ", removed "
            << (db.options.removeFrames.empty() ? "none"
                                                : formatFrameRange(db.options.removeFrames))
            << ", duplicate tolerance " << db.options.duplicateTolerance << " of the diagonal\n";
  for (std::size_t c = 0; c < db.extraClips.size(); ++c) {
    const ReferenceClipSource& clip = db.extraClips[c];
    std::cout << "  reference clip " << c + 2 << " (pose model only): driver " << clip.driverSource
              << ", driven " << clip.drivenSource << ", frames "
              << (clip.frames.empty() ? std::string("none") : formatFrameRange(clip.frames))
              << " (model frames + " << clip.frameOffset << ")\n";
  }
  const PoseModel& model = db.poseModel;
  if (model.empty()) {
    std::cout << "  pose model: none (bakes blend the picks with QP weights)\n";
  } else {
    std::cout << "  pose model: " << model.partCount() << " rigid parts, " << model.frameCount()
              << " reference frames, " << model.featureCount() << " features (velocity over "
              << model.velocityLag << ", history over " << model.historyFrames << " frames";
    if (model.siblingWeight > 0.0) {
      std::cout << ", sibling parts at weight " << model.siblingWeight;
    }
    std::cout << "), rank " << model.rank() << "; cross-validated mean vertex error "
              << model.crossValidationError << " (binding " << model.bindingError
              << "), predicted error " << model.errorBias << " + " << model.errorScale << " sigma";
    if (model.clipMixtureWeight > 0.0) {
      std::cout << "; per-clip models of " << model.clipSizes.size()
                << " clips mixed in (weight of the model over every clip "
                << model.clipMixtureWeight << ")";
    }
    if (model.verdictLevel > 0.0) {
      std::cout << "; error bound: predicted + " << model.verdictMargin << " (holds on "
                << 100.0 * model.verdictLevel << "% of held-out reference frames), never below "
                << model.smallestErrorBound() << " ("
                << percentOfDiagonal(model.smallestErrorBound(), db.drivenMesh)
                << "% of the cloth's rest diagonal: a lower coverage tolerance flags every frame)";
    }
    std::cout << "\n";
  }
  if (db.drivenSides.empty()) {
    std::cout << "  side table: none (a bake learns it when it starts; rebuild the database "
                 "with this drivenshape to store it)\n";
  } else {
    std::cout << "  side table: "
              << std::count(db.drivenSides.begin(), db.drivenSides.end(), kSideInside) << " of "
              << db.drivenVertexCount() << " driven vertices live inside the driver\n";
  }
  std::cout << "  picks (order, source frame, reason, RMS distance to earlier picks):\n";
  for (int i = 0; i < db.shapeCount(); ++i) {
    std::cout << "    " << std::setw(3) << i << "  frame " << std::setw(6) << db.frames[i] << "  "
              << std::setw(8) << pickReasonName(db.reasons[i]) << "  " << db.pickDistances[i]
              << "\n";
  }
}

void infoExr(const std::string& path) {
  const ExrPointCacheInfo info = readPointCacheExrInfo(path);
  std::cout << "point-cache EXR " << path << "\n"
            << "  " << info.vertexCount << " vertices, frame " << info.frame << ", width "
            << info.width << ", compression " << exrCompressionName(info.compression)
            << (info.hasNormals ? ", normals" : "") << "\n"
            << "  topology " << hashToHex(info.topologyHash) << ", settings "
            << hashToHex(info.settingsHash) << ", written by drivenshape " << info.toolVersion
            << ", " << info.framesPerSecond << " fps\n"
            << "  bounds (" << info.bounds.min.transpose() << ") - (" << info.bounds.max.transpose()
            << ")\n";
}

void infoPositionMap(const std::string& path) {
  const PositionMapInfo info = readPositionMapExrInfo(path);
  std::cout << "position-map EXR " << path << "\n"
            << "  " << info.width << "x" << info.height << " texels, frame " << info.frame
            << ", padding " << info.padding << " texels, compression "
            << exrCompressionName(info.compression)
            << (info.hasNormals ? (info.halfNormals ? ", normals (half)" : ", normals") : "")
            << "\n"
            << "  mesh of " << info.meshVertexCount << " vertices, topology "
            << hashToHex(info.topologyHash) << ", written by drivenshape " << info.toolVersion
            << ", " << info.framesPerSecond << " fps\n"
            << "  bounds (" << info.bounds.min.transpose() << ") - (" << info.bounds.max.transpose()
            << ")\n";
  const std::vector<std::string> names = positionMapChannelNames(info.channels, info.hasNormals);
  std::cout << "  channels (" << positionMapChannelsName(info.channels) << "): " << names[0] << " "
            << names[1] << " " << names[2] << " = position, " << names[3] << " = coverage";
  if (info.hasNormals) {
    std::cout << ", " << names[4] << " " << names[5] << " " << names[6] << " = normals";
  }
  std::cout << "\n";
}

/// A single EXR: a position map or a point cache, by its header.
void infoAnyExr(const std::string& path) {
  if (isPositionMapExr(path)) {
    infoPositionMap(path);
  } else {
    infoExr(path);
  }
}

}  // namespace

int runDevices(const std::vector<std::string>& args) {
  ArgParser parser("drivenshape devices",
                   "Lists the OpenCL platforms and devices with the "
                   "index that `--device` accepts.");
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  printDevices(std::cout);
  return 0;
}

int runInfo(const std::vector<std::string>& args) {
  ArgParser parser(
      "drivenshape info FILE",
      "Describes a database, a mesh (.obj), a PC2 cache, a point-cache or position-map "
      "EXR, or a point-cache sequence pattern (name.####.exr).");
  parser.positional("one FILE", 1);
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const std::string path = parser.positionals().front();
  if (!hasFramePattern(path)) {
    requireRegularFile(path, "file");
  }
  if (hasFramePattern(path)) {
    // Every frame's header, against its name and the others (a copied or foreign frame).
    const ExrSequenceInfo sequence = checkPointCacheExrSequence(path);
    std::cout << "EXR sequence " << path << ": " << sequence.frames.size() << " frames ("
              << formatFrameRange(sequence.frames) << "), " << sequence.first.vertexCount
              << " vertices; every frame's header matches its name, vertex count and topology\n";
    infoExr(sequence.files.front());
  } else if (endsWith(path, ".obj")) {
    const Mesh mesh = readObj(path);
    std::cout << "mesh " << path << "\n";
    printMesh("  ", mesh);
  } else if (endsWith(path, ".pc2")) {
    const auto cache = openPc2(path);
    const std::vector<int> frames = cache->frames();
    std::cout << "PC2 cache " << path << ": " << cache->vertexCount() << " points, "
              << frames.size() << " frames ("
              << (frames.empty() ? std::string("none") : formatFrameRange(frames)) << ")\n";
  } else if (endsWith(path, ".exr")) {
    infoAnyExr(path);
  } else if (isDatabaseFile(path)) {
    infoDatabase(path);
  } else if (!std::filesystem::exists(path)) {
    DS_THROW(kInput, "'", path, "' does not exist");
  } else {
    DS_THROW(kInput, "'", path, "' is not a database, .obj, .pc2 or .exr file");
  }
  return 0;
}

namespace {

/// Threads for host work: --threads if given, else the farm's SLURM_CPUS_PER_TASK, else 0
/// (all cores).
int threadsFor(int requested) {
  int threads = 0;
  std::string source = "--threads";
  if (requested > 0) {
    threads = requested;
  } else if (const char* slurm = std::getenv("SLURM_CPUS_PER_TASK")) {
    threads = std::max(0, std::atoi(slurm));
    source = "SLURM_CPUS_PER_TASK";
  }
  const int clamped = clampThreads(threads);
  if (clamped != threads) {
    std::cerr << "note: " << source << " asks for " << threads << " threads; this machine has "
              << hardwareThreads() << " hardware threads, using " << clamped << "\n";
  }
  return clamped;
}

/// The frames of one farm chunk: --chunk-size N frames starting at chunk --chunk-index of
/// --frames (in the order given); `index` receives the chunk index. Frame numbers are never
/// array indices.
std::vector<int> farmChunk(const std::vector<int>& frames, const ArgParser& parser, int& index) {
  if (!parser.has("--chunk-size") || !parser.has("--chunk-index")) {
    DS_THROW(kUsage, "--chunk-size and --chunk-index go together");
  }
  const int size = parser.getInt("--chunk-size", 1);
  if (parser.get("--chunk-index") == "env") {
    const char* text = std::getenv("SLURM_ARRAY_TASK_ID");
    if (text == nullptr || *text == '\0') {
      DS_THROW(kUsage,
               "--chunk-index env: SLURM_ARRAY_TASK_ID is not set (run inside a Slurm "
               "array job, or pass the index)");
    }
    char* end = nullptr;
    const long value = std::strtol(text, &end, 10);
    if (*end != '\0' || value < 0 || value > 1000000) {
      DS_THROW(kUsage, "--chunk-index env: SLURM_ARRAY_TASK_ID='", text, "' is not a chunk index");
    }
    index = static_cast<int>(value);
  } else {
    index = parser.getInt("--chunk-index", 0);
  }
  const int chunks = static_cast<int>((frames.size() + size - 1) / size);
  if (index >= chunks) {
    DS_THROW(kUsage, "--chunk-index ", index, " is past the last chunk: ", frames.size(),
             " frames in chunks of ", size, " make ", chunks, " chunks (0-", chunks - 1, ")");
  }
  const auto first = frames.begin() + static_cast<std::ptrdiff_t>(index) * size;
  const auto last =
      frames.begin() + std::min<std::ptrdiff_t>(static_cast<std::ptrdiff_t>(index + 1) * size,
                                                static_cast<std::ptrdiff_t>(frames.size()));
  return std::vector<int>(first, last);
}

/// Set by SIGINT/SIGTERM; the bake stops at the next chunk boundary.
std::atomic<bool> gStopRequested{false};

extern "C" void onStopSignal(int) {
  gStopRequested = true;
}

class CliObserver : public BakeObserver {
 public:
  /// `verbose`: a line per frame on a terminal too (instead of the bar), with the frame's
  /// predicted error and verdict.
  CliObserver(long total, bool quiet, bool verbose)
      : mProgress("bake", quiet || verbose ? 0 : total), mQuiet(quiet), mVerbose(verbose) {}
  bool stopRequested() override { return gStopRequested.load(); }
  /// Position maps straight from the baked positions (bake --posmap).
  void setPositionMaps(std::unique_ptr<PositionMapWriter> writer, std::string pattern) {
    mMaps = std::move(writer);
    mMapPattern = std::move(pattern);
  }
  void batchBaked(const std::vector<const FrameRecord*>& records, const float* positions) override {
    if (!mMaps) {
      return;
    }
    std::vector<int> frames;
    std::vector<std::string> paths;
    for (const FrameRecord* record : records) {
      frames.push_back(record->frame);
      paths.push_back(expandFramePattern(mMapPattern, record->frame));
    }
    mMaps->writeFrames(frames, positions, paths);
  }
  void warning(const std::string& message) override {
    // Warnings are shown even with --quiet: they question the inputs.
    std::fprintf(stderr, "%swarning: %s\n", mProgress.isTerminal() && !mQuiet ? "\n" : "",
                 message.c_str());
  }
  void frameDone(const FrameRecord& record, double seconds) override {
    if (mQuiet) {
      return;
    }
    if (mVerbose) {
      std::fprintf(stderr, "frame %d baked in %.4f s, residual %.3e%s -> %s\n", record.frame,
                   seconds, record.relativeResidual, verdictText(record).c_str(),
                   record.output.c_str());
      return;
    }
    if (!mProgress.isTerminal()) {
      std::fprintf(stderr, "frame %d baked in %.4f s, residual %.3e -> %s\n", record.frame, seconds,
                   record.relativeResidual, record.output.c_str());
    }
    mProgress.advance();
  }
  void finish() {
    if (!mQuiet && !mVerbose) {
      mProgress.finish();
    }
  }

 private:
  /// ", predicted error E, simulate" for a frame the pose model predicted, else "".
  static std::string verdictText(const FrameRecord& record) {
    if (record.predictedError < 0) {
      return "";
    }
    std::ostringstream text;
    text << ", predicted error " << std::setprecision(4) << record.predictedError << ", bound "
         << record.errorBound << (record.flagged > 0 ? ", simulate" : ", enough");
    return text.str();
  }

  Progress mProgress;
  bool mQuiet;
  bool mVerbose;
  std::unique_ptr<PositionMapWriter> mMaps;
  std::string mMapPattern;
};

/// out/cloth.####.exr -> out/cloth.posmap.####.exr
std::string defaultPosmapPattern(const std::string& pattern) {
  const std::filesystem::path path(pattern);
  std::string name = path.filename().string();
  const std::size_t token = framePatternPosition(name);
  name.insert(token == std::string::npos ? 0 : token, "posmap.");
  return (path.parent_path() / name).string();
}

/// The bake command after its arguments are parsed.
int bakeParsed(const ArgParser& parser);

}  // namespace

ArgParser bakeParser() {
  ArgParser parser(
      "drivenshape bake --db DB --driver CACHE --frames RANGE -o OUT.####.exr",
      "Bakes a shot: for each frame of the driver cache, fits it rigidly to the database's rest "
      "driver (--align), solves the blend weights of the database shapes (min ||A w - b||, "
      "sum w = 1, 0 <= w <= 1), blends the cloth shapes with them (as offsets in local "
      "triangle frames bound at rest, or as world positions corrected onto the shot's driver "
      "like the 2008 talk: --blend), rebuilds them on the shot's driver, moves cloth out of "
      "the body (--skin-offset), applies layers (--mix, --wind-*) and writes one point-cache "
      "EXR per frame. Frames are evaluated a batch at a time with OpenCL kernels (or the host "
      "reference path); reading and writing overlap the kernels. The talk's method exactly: "
      "--align none --blend world --no-resolve.");
  parser.option("--db", "DB", "database from `drivenshape db build`", "", true)
      .option("--driver", "CACHE", "shot driver cache (.pc2 or name.####.exr)", "", true)
      .option("--frames", "RANGE", "frames to bake: 1001-1100, 1001-1100x2, 1001,1005", "", true)
      .option("-o", "OUT.####.exr", "output EXR sequence (####, %04d or $F4)", "", true)
      .option("--report", "PATH", "per-bake JSON report", "OUT folder/<name>.report.json")
      .option("--device", "SPEC", "auto, host, cpu, gpu, an index or a name substring", "auto")
      .settings()
      .option("--chunk-size", "N", "farm chunk: bake only chunk --chunk-index of N frames")
      .option("--chunk-index", "I|env",
              "which chunk (0-based) of --frames; env reads SLURM_ARRAY_TASK_ID")
      .option("--posmap", "W[xH]", "also write UV-space position maps of the baked cloth")
      .option("--posmap-out", "PATTERN", "position-map EXR sequence",
              "OUT with .posmap before the frame token")
      .option("--posmap-padding", "N", "texels of padding around UV islands", "8")
      .option("--posmap-channels", "NAMING",
              "position-map channels: rgba (R G B, A, N.R N.G N.B) or legacy (P.X P.Y P.Z, A, "
              "N.X N.Y N.Z)",
              "rgba")
      .flag("--posmap-normals", "add the normals (N.R N.G N.B) to the position maps")
      .flag("--skip-existing", "keep outputs that are complete and match this bake")
      .flag("--force",
            "bake a driver the sanity check refuses (another scale than the database's, or "
            "edges that do not correspond); its findings become warnings")
      .flag("--untrusted-driver",
            "bake a database whose driver mesh is not closed, manifold and consistently "
            "oriented (refused otherwise), without the audit and the penetration resolution; "
            "a warning and the report say so")
      .flag("--sync",
            "fsync every output before its atomic rename (survives a power loss; costs a disk "
            "or NFS round trip per frame)")
      .flag("--quiet", "no progress or per-frame lines")
      .flag("--verbose", "also print every setting, a line per frame and the seconds per stage")
      .epilog(
          "Exit codes: 0 ok, 2 usage, 3 input, 4 output, 5 OpenCL device, 6 numerical, "
          "7 interrupted.");
  addLayerFlags(parser);
  return parser;
}

int runBake(const std::vector<std::string>& args) {
  ArgParser parser = bakeParser();
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  // Farm tasks are stopped with SIGTERM (and users press Ctrl-C): from here on, through the
  // setup too, a stop finishes the batch in hand, keeps every complete frame, leaves no
  // temporary file and exits with code 7. A stop can also break the setup itself (LLVM inside
  // PoCL deletes its temporary files on SIGTERM, failing a kernel build): an error after a
  // stop request is reported as the interruption it is.
  std::signal(SIGTERM, onStopSignal);
  std::signal(SIGINT, onStopSignal);
  try {
    return bakeParsed(parser);
  } catch (const Error& error) {
    if (gStopRequested.load() && error.code() != ErrorCode::kInterrupted) {
      DS_THROW(kInterrupted, "stopped by a signal before the bake finished (", error.what(),
               "); finished frames are complete, rerun with --skip-existing to resume");
    }
    throw;
  }
}

namespace {

/// The files a bake writes, as the options name them: the frames, the report, the position maps.
std::vector<NamedPath> bakeOutputs(const BakeOptions& options, const std::string& posmapPattern) {
  std::vector<NamedPath> outputs = {{"-o", options.outputPattern, true},
                                    {"--report", options.reportPath, false}};
  if (!posmapPattern.empty()) {
    outputs.push_back({"--posmap-out", posmapPattern, true});
  }
  return outputs;
}

/// Refuses a bake whose outputs (frames, report, position maps) name the same file, or would
/// overwrite one of its inputs: the database, the maps, every frame of the driver and --mix
/// sequences (history frames before --frames too), by name and by file identity.
void checkBakePaths(const ArgParser& parser, const BakeOptions& options,
                    const std::string& posmapPattern) {
  const std::vector<NamedPath> outputs = bakeOutputs(options, posmapPattern);
  std::vector<NamedPath> inputs =
      givenPaths(parser, {"--db", "--bind", "--regions", "--mix-weight", "--wind-weight"});
  const std::vector<NamedPath> caches = givenPaths(parser, {"--driver", "--mix"}, true);
  inputs.insert(inputs.end(), caches.begin(), caches.end());
  checkDistinctPaths(outputs, options.frames, inputs);
}

/// Creates the missing folders of the bake's outputs (frames, report, position maps).
void createBakeFolders(const BakeOptions& options, const std::string& posmapPattern, bool quiet) {
  std::vector<std::string> paths;
  for (const NamedPath& output : bakeOutputs(options, posmapPattern)) {
    if (!output.path.empty()) {
      paths.push_back(output.sequence ? expandFramePattern(output.path, options.frames.front())
                                      : output.path);
    }
  }
  createOutputFoldersFor(paths, quiet);
}

/// The bake's options from its command line (settings through the settings table), every value
/// checked; opens no file and leaves the threads as given (threadsFor resolves them).
BakeOptions bakeOptions(const ArgParser& parser) {
  BakeOptions options;
  options.frames = parseFrameRange(parser.get("--frames"));
  options.outputPattern = parser.get("-o");
  options.reportPath =
      parser.has("--report") ? parser.get("--report") : defaultReportPath(options.outputPattern);
  readSettings(parser, options);
  if (parser.has("--chunk-size") || parser.has("--chunk-index")) {
    int chunkIndex = 0;
    options.shotFrames = options.frames;
    options.frames = farmChunk(options.frames, parser, chunkIndex);
    if (!parser.has("--report")) {
      // Farm chunks run side by side: one report each (<name>.chunk<I>.report.json).
      const std::string suffix = ".report.json";
      options.reportPath.insert(options.reportPath.size() - suffix.size(),
                                ".chunk" + std::to_string(chunkIndex));
    }
  }
  options.layers = readLayerFlags(parser, options.framesPerSecond);
  options.skipExisting = parser.has("--skip-existing");
  options.force = parser.has("--force");
  options.syncOutputs = parser.has("--sync");
  if (options.evaluator.maxWeightChange > 0 && parser.has("--chunk-size")) {
    const int farmChunk = parser.getInt("--chunk-size", 1);
    if (farmChunk % options.batchFrames != 0) {
      DS_THROW(kUsage, "with --max-weight-change, --chunk-size (", farmChunk,
               ") must be a multiple of --batch (", options.batchFrames,
               ") so that every farm chunk reproduces the single bake; e.g. pass --batch ",
               std::gcd(farmChunk, options.batchFrames), " to both");
    }
  }
  if (!hasFramePattern(options.outputPattern)) {
    DS_THROW(kUsage, "-o '", options.outputPattern,
             "' has no frame token; use e.g. out/cloth.####.exr");
  }
  return options;
}

/// The position-map pattern of `bake --posmap`, or "" without it.
std::string posmapPatternOf(const ArgParser& parser, const BakeOptions& options) {
  if (!parser.has("--posmap")) {
    return "";
  }
  const std::string pattern = parser.has("--posmap-out")
                                  ? parser.get("--posmap-out")
                                  : defaultPosmapPattern(options.outputPattern);
  if (!hasFramePattern(pattern)) {
    DS_THROW(kUsage, "--posmap-out '", pattern, "' has no frame token");
  }
  return pattern;
}

/// The position maps' options of `bake --posmap`, each value checked.
PositionMapOptions positionMapOptions(const ArgParser& parser, const BakeOptions& options) {
  PositionMapOptions maps;
  std::tie(maps.width, maps.height) =
      parsePositionMapResolution(parser.get("--posmap"), "--posmap");
  maps.padding = parser.getInt("--posmap-padding", 0);
  if (maps.padding > kMaxPositionMapPadding) {
    DS_THROW(kUsage, "--posmap-padding ", maps.padding, " is outside 0..", kMaxPositionMapPadding,
             " texels");
  }
  maps.normals = parser.has("--posmap-normals");
  maps.channels = parsePositionMapChannels(parser.get("--posmap-channels"), "--posmap-channels");
  maps.compression = options.compression;
  maps.zipEncoder = options.zipEncoder;
  maps.framesPerSecond = options.framesPerSecond;
  maps.threads = options.threads;
  return maps;
}

/// Position maps straight from the baked positions (bake --posmap) into `pattern`.
void attachPositionMaps(const ArgParser& parser, const BakeOptions& options, const Database& db,
                        Device& target, const std::string& pattern, CliObserver& observer) {
  const PositionMapOptions maps = positionMapOptions(parser, options);
  observer.setPositionMaps(
      std::make_unique<PositionMapWriter>(db.drivenMesh, maps, target.makePositionMaps(),
                                          "the database's driven mesh", &std::cerr),
      pattern);
}

/// The audit's summary line: cloth vertices inside the driver per frame, binding switches, the
/// largest jump.
void printAudit(const BakeResult& result, const BakeOptions& options) {
  // Counts that a mode does not measure are -1 in the records (local blending has no
  // blended cloth to audit, world blending no binding switches to report).
  long before = 0, corrected = 0, after = 0, switches = 0;
  bool hasBefore = false, hasSwitches = false;
  double jump = 0;
  for (const FrameRecord& record : result.frames) {
    if (!record.skipped) {
      hasBefore = hasBefore || record.insideBefore >= 0;
      hasSwitches = hasSwitches || record.bindingSwitches >= 0;
      before += std::max(record.insideBefore, 0);
      corrected += std::max(record.insideCorrected, 0);
      after += record.insideAfter;
      switches += std::max(record.bindingSwitches, 0);
      jump = std::max(jump, record.maxJump);
    }
  }
  const double frames = result.baked;
  std::cout << "audit:   cloth vertices inside the driver per frame: " << std::setprecision(1);
  if (hasBefore) {
    std::cout << before / frames << " blended, ";
  }
  std::cout << corrected / frames << (options.evaluator.correct ? " corrected" : " (no correction)")
            << ", " << after / frames
            << (options.evaluator.resolve ? " after resolution" : " written");
  if (hasSwitches) {
    std::cout << "; binding switches " << switches;
  }
  std::cout << "; largest frame-to-frame jump " << std::setprecision(4) << jump << "\n";
}

/// What a finished bake says on stderr (frames baked again, stale files) and stdout.
void printBakeSummary(const BakeResult& result, const BakeOptions& options,
                      const std::string& posmapPattern, const std::string& device) {
  for (const FrameRecord& record : result.frames) {
    if (!record.rebakeReason.empty()) {
      std::cerr << "rebaked frame " << record.frame << ": the existing " << record.output << " "
                << record.rebakeReason << "\n";
    }
  }
  if (result.staleTempFilesRemoved > 0) {
    std::cerr << "removed " << result.staleTempFilesRemoved
              << " temporary files left by an interrupted run\n";
  }
  const double fps = result.times.total > 0 ? result.baked / result.times.total : 0.0;
  std::cout << "baked " << result.baked << " frames (" << result.skipped << " kept) in "
            << std::fixed << std::setprecision(3) << result.times.total << " s, "
            << std::setprecision(1) << fps << " frames/s on " << device << "\n"
            << "outputs: " << absolute(options.outputPattern) << " (frames "
            << formatFrameRange(options.frames) << ")\n";
  if (!posmapPattern.empty()) {
    std::cout << "posmaps: " << absolute(posmapPattern) << "\n";
  }
  if (!options.reportPath.empty()) {
    std::cout << "report:  " << absolute(options.reportPath) << "\n";
  }
  if (options.evaluator.audit && result.baked > 0) {
    printAudit(result, options);
  }
}

/// bake --verbose: every setting of the settings table by its label, with its value and, where
/// it is not the default, the default.
void printSettings(const BakeOptions& options) {
  std::cerr << "settings:\n";
  for (const Setting& setting : settingsTable()) {
    if (setting.flag == nullptr || !hasBakeValue(setting)) {
      continue;
    }
    const std::string text = formatSettingValue(settingValue(setting, options));
    const std::string fallback = formatSettingValue(defaultSettingValue(setting));
    std::string unit = *setting.unit != '\0' ? std::string(" ") + setting.unit : "";
    if (text == "0" && *setting.zero != '\0') {
      unit += std::string(" (") + setting.zero + ")";
    }
    std::cerr << "  " << std::left << std::setw(24) << setting.label
              << (text.empty() ? "-" : text + unit)
              << (text == fallback ? "" : "  (default " + (fallback.empty() ? "-" : fallback) + ")")
              << "\n";
  }
}

/// bake --verbose: the seconds of each stage over the whole bake.
void printStageSeconds(const BakeResult& result) {
  std::cerr << "seconds:" << std::fixed << std::setprecision(3);
  for (const auto& [stage, seconds] : result.times.stages) {
    std::cerr << " " << stage << " " << seconds << ",";
  }
  std::cerr << " read " << result.times.read << ", write " << result.times.write << ", setup "
            << result.times.setup << ", total " << result.times.total << "\n";
  std::cerr.unsetf(std::ios::floatfield);
}

/// Refuses frames the driver cache does not hold before any work per frame (a typo such as
/// --frames 1-10000000 fails in a second, not after names for every frame are made). A driver
/// that cannot be opened is left to the full check, after the usage checks.
void checkDriverHasFrames(const std::string& path, const std::vector<int>& frames) {
  std::unique_ptr<PointCacheReader> driver;
  try {
    driver = openPointCache(path, 0);
  } catch (const Error&) {
    return;
  }
  for (int frame : frames) {
    if (!driver->hasFrame(frame)) {
      DS_THROW(kInput, "driver cache '", path, "' has no frame ", frame, " (it holds ",
               formatFrameRange(driver->frames()), "); bake frames within that range");
    }
  }
}

/// Refuses --quiet with --verbose.
void checkQuietOrVerbose(const ArgParser& parser) {
  if (parser.has("--quiet") && parser.has("--verbose")) {
    DS_THROW(kUsage, "--quiet and --verbose contradict each other; give one");
  }
}

int bakeParsed(const ArgParser& parser) {
  BakeOptions options = bakeOptions(parser);
  options.threads = options.evaluator.threads = threadsFor(options.threads);
  const std::string posmapPattern = posmapPatternOf(parser, options);
  checkQuietOrVerbose(parser);
  checkDriverHasFrames(parser.get("--driver"), options.frames);
  checkBakePaths(parser, options, posmapPattern);
  // Missing output folders are created once the inputs have loaded (createBakeFolders); the
  // report's place is checked now too, not after the bake.
  missingOutputFolders(expandFramePattern(options.outputPattern, options.frames.front()));
  if (!options.reportPath.empty()) {
    missingOutputFolders(options.reportPath);
  }

  const Database db = loadDatabase(parser.get("--db"));
  admitDriverMesh(db, parser.get("--db"), parser.has("--untrusted-driver"), options);
  // EXR driver caches carry a topology hash: it must be the database's driver mesh.
  const auto driver = openPointCache(parser.get("--driver"), topologyHash(db.driverMesh));
  if (options.threads > 0 && std::getenv("POCL_MAX_PTHREAD_COUNT") == nullptr) {
    // PoCL reads this when the platform loads: cap its worker threads like ours.
    ::setenv("POCL_MAX_PTHREAD_COUNT", std::to_string(options.threads).c_str(), 0);
  }
  const std::unique_ptr<Device> target = openCliDevice(parser.get("--device"), std::cerr);
  const std::string device = target->description();
  const bool quiet = parser.has("--quiet");
  const bool verbose = parser.has("--verbose");
  createBakeFolders(options, posmapPattern, quiet);
  if (verbose) {
    printSettings(options);
  }
  if (!quiet) {
    std::cerr << "baking " << options.frames.size() << " frames ("
              << formatFrameRange(options.frames) << ") on " << device << "\n";
  }
  CliObserver observer(static_cast<long>(options.frames.size()), quiet, verbose);
  if (!posmapPattern.empty()) {
    attachPositionMaps(parser, options, db, *target, posmapPattern, observer);
  }
  const BakeResult result = bake(db, *driver, *target, options, &observer);
  observer.finish();
  if (verbose) {
    printStageSeconds(result);
  }
  printBakeSummary(result, options, posmapPattern, device);
  return 0;
}

}  // namespace

void checkBakeArguments(const std::vector<std::string>& args) {
  ArgParser parser = bakeParser();
  if (!parser.parse(args)) {
    DS_THROW(kUsage, "--help asks for the bake's help instead of a bake");
  }
  const BakeOptions options = bakeOptions(parser);
  if (!posmapPatternOf(parser, options).empty()) {
    positionMapOptions(parser, options);
  }
  checkQuietOrVerbose(parser);
}

}  // namespace drivenshape::cli
