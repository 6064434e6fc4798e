// SPDX-License-Identifier: Apache-2.0
#include "export_command.h"

#include <iostream>
#include <memory>
#include <optional>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

#include "atomic_file.h"
#include "up_axis.h"

#include "cli_args.h"

namespace drivenshape::cli {
namespace {

/// PC2 holds evenly spaced samples: the frames must be ascending with one step (the rate).
int sampleStep(const std::vector<int>& frames, const std::string& text) {
  if (frames.size() < 2) {
    return 1;
  }
  const long long step = static_cast<long long>(frames[1]) - frames[0];
  for (std::size_t i = 1; i < frames.size(); ++i) {
    if (static_cast<long long>(frames[i]) - frames[i - 1] != step || step <= 0) {
      DS_THROW(kUsage, "--frames ", text,
               ": a PC2 file holds evenly spaced frames in ascending order (e.g. 1001-1100 or "
               "1001-1100x2); frames ",
               frames[i - 1], " and ", frames[i], " break the step of ", step);
    }
  }
  return static_cast<int>(step);
}

/// The PC2 header stores the start frame and the rate as float32, which holds every whole number
/// up to 2^24 exactly: past that, the frames a reader computes (start + s * rate) would not be
/// the frames written.
void checkFramesFitPc2(const std::vector<int>& frames, const std::string& text) {
  constexpr int kLargestExactFrame = 1 << 24;
  for (int frame : frames) {
    if (frame > kLargestExactFrame || frame < -kLargestExactFrame) {
      DS_THROW(kUsage, "--frames ", text, ": frame ", frame,
               " cannot be stored exactly in a PC2 header (float32 start frame); PC2 frames must "
               "lie within -16777216..16777216");
    }
  }
}

ArgParser exportParser() {
  ArgParser parser(
      "drivenshape export --cache CACHE --frames RANGE [--pc2 OUT.pc2] "
      "[--obj FIRST.obj --mesh DRIVEN.obj] [--up-axis Z|Y]",
      "Writes a baked result as guides for a cloth simulation: --pc2 writes the frames as one "
      "PC2 point cache (little-endian; header POINTCACHE2, version 1, points, start frame, "
      "sample rate, samples: what Blender's Mesh Cache modifier and Maya's PC2 conversion "
      "read) to use as goal or pin targets; --obj writes the first frame with the "
      "faces, UVs and groups of the driven rest mesh, for an initial drape. --up-axis Y rotates "
      "the points of both from drivenshape's Z up to Y up, (x, y, z) -> (x, z, -y), exactly. "
      "Import settings for Blender, Houdini and Maya: docs/conventions.md. Files are written "
      "atomically (a temporary file renamed into place).");
  parser.option("--cache", "CACHE", "the result to export (.pc2 or name.####.exr)", "", true)
      .option("--frames", "RANGE",
              "frames to export, evenly spaced for --pc2: 1001-1100 or 1001-1100x2", "", true)
      .option("--pc2", "OUT.pc2", "write the frames as one PC2 (sample rate = the range's step)")
      .option("--obj", "FIRST.obj", "write the first frame as OBJ (needs --mesh)")
      .option("--mesh", "DRIVEN.obj",
              "driven rest mesh: its faces, UVs and groups for --obj, and the topology an EXR "
              "cache must carry")
      .option("--up-axis", "Z|Y",
              "up axis of the written points: Z keeps them as they are (drivenshape's axis); Y "
              "rotates them -90 degrees about X, (x, y, z) -> (x, z, -y), for Y-up tools",
              "Z")
      .flag("--quiet", "no progress lines")
      .epilog("Exit codes: 0 ok, 2 usage, 3 input, 4 output.");
  return parser;
}

/// What to export, checked before anything is read.
struct ExportRequest {
  bool pc2 = false;
  bool obj = false;
  UpAxis upAxis = UpAxis::kZ;
  std::vector<int> frames;
  int step = 1;  ///< the PC2 sample rate
};

ExportRequest exportRequestFrom(const ArgParser& parser) {
  ExportRequest request;
  request.pc2 = parser.has("--pc2");
  request.obj = parser.has("--obj");
  if (!request.pc2 && !request.obj) {
    DS_THROW(kUsage, "`drivenshape export` needs --pc2 OUT.pc2 and/or --obj FIRST.obj");
  }
  if (request.obj && !parser.has("--mesh")) {
    DS_THROW(kUsage, "--obj needs --mesh DRIVEN.obj (the rest mesh whose faces and UVs to keep)");
  }
  request.upAxis = parseUpAxis(parser.get("--up-axis"), "--up-axis");
  const std::string rangeText = parser.get("--frames");
  request.frames = parseFrameRange(rangeText);
  request.step = request.pc2 ? sampleStep(request.frames, rangeText) : 1;
  if (request.pc2) {
    checkFramesFitPc2(request.frames, rangeText);
    checkOutputFolderWritable(parser.get("--pc2"));
  }
  if (request.obj) {
    checkOutputFolderWritable(parser.get("--obj"));
  }
  std::vector<NamedPath> inputs = givenPaths(parser, {"--cache"}, true);
  const std::vector<NamedPath> mesh = givenPaths(parser, {"--mesh"});
  inputs.insert(inputs.end(), mesh.begin(), mesh.end());
  checkDistinctPaths(givenPaths(parser, {"--pc2", "--obj"}), request.frames, inputs);
  return request;
}

/// Opens --cache (an EXR's topology must be the mesh's) and checks it has the mesh's vertex
/// count and every frame.
std::unique_ptr<PointCacheReader> openExportCache(const ArgParser& parser,
                                                  const std::optional<Mesh>& mesh,
                                                  const std::vector<int>& frames) {
  const std::string cachePath = parser.get("--cache");
  auto cache = openPointCache(cachePath, mesh ? topologyHash(*mesh) : 0);
  const int vertexCount = cache->vertexCount();
  if (mesh && mesh->vertexCount() != vertexCount) {
    DS_THROW(kInput, cachePath, " has ", vertexCount, " vertices but --mesh ", parser.get("--mesh"),
             " has ", mesh->vertexCount(), "; pass the driven mesh the cache was baked for");
  }
  for (int frame : frames) {
    if (!cache->hasFrame(frame)) {
      DS_THROW(kInput, cachePath, ": frame ", frame, " is missing; the cache holds frames ",
               formatFrameRange(cache->frames()));
    }
  }
  return cache;
}

/// --obj: the first frame on the rest mesh's faces, UVs and groups.
void exportFirstFrameObj(const std::string& out, const PointCacheReader& cache, Mesh& mesh,
                         const ExportRequest& request) {
  const int vertexCount = cache.vertexCount();
  std::vector<float> xyz(3 * static_cast<std::size_t>(vertexCount));
  cache.readFrame(request.frames.front(), xyz.data());
  convertUpAxis(xyz.data(), static_cast<std::size_t>(vertexCount), UpAxis::kZ, request.upAxis);
  mesh.positions = Eigen::Map<const Positions>(xyz.data(), vertexCount, 3);
  writeObj(out, mesh);
  std::cout << "wrote " << out << " (frame " << request.frames.front() << ", " << vertexCount
            << " vertices, " << mesh.faceCount() << " faces" << (mesh.hasUvs() ? ", UVs" : "")
            << ", " << upAxisName(request.upAxis) << " up)\n";
}

/// --pc2: every frame, one sample each, with progress lines every 100 frames unless `quiet`.
void exportPc2(const std::string& out, const PointCacheReader& cache, const ExportRequest& request,
               bool quiet) {
  const std::vector<int>& frames = request.frames;
  const int vertexCount = cache.vertexCount();
  std::vector<float> xyz(3 * static_cast<std::size_t>(vertexCount));
  Pc2Writer writer(out, vertexCount, static_cast<float>(frames.front()),
                   static_cast<int>(frames.size()), static_cast<float>(request.step));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    cache.readFrame(frames[i], xyz.data());
    convertUpAxis(xyz.data(), static_cast<std::size_t>(vertexCount), UpAxis::kZ, request.upAxis);
    writer.writeFrame(xyz.data());
    if (!quiet && (i + 1) % 100 == 0) {
      std::cerr << "export: " << i + 1 << " of " << frames.size() << " frames\n";
    }
  }
  writer.commit();
  std::cout << "wrote " << out << " (" << frames.size() << " frames " << formatFrameRange(frames)
            << ", start " << frames.front() << ", sample rate " << request.step << ", "
            << vertexCount << " points, " << upAxisName(request.upAxis) << " up)\n";
}

}  // namespace

int runExport(const std::vector<std::string>& args) {
  ArgParser parser = exportParser();
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const ExportRequest request = exportRequestFrom(parser);
  std::optional<Mesh> mesh;
  if (parser.has("--mesh")) {
    mesh = readObj(parser.get("--mesh"));
  }
  const auto cache = openExportCache(parser, mesh, request.frames);
  if (request.obj) {
    exportFirstFrameObj(parser.get("--obj"), *cache, *mesh, request);
  }
  if (request.pc2) {
    exportPc2(parser.get("--pc2"), *cache, request, parser.has("--quiet"));
  }
  return 0;
}

}  // namespace drivenshape::cli
