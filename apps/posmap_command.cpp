// SPDX-License-Identifier: Apache-2.0
#include "posmap_command.h"

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/position_map.h>
#include <drivenshape/position_map_sequence.h>

#include "atomic_file.h"
#include "hash.h"
#include "progress.h"

#include "cli_args.h"
#include "device_choice.h"

namespace drivenshape::cli {

namespace {

ArgParser posmapParser() {
  ArgParser parser(
      "drivenshape posmap --mesh M.obj --cache CACHE --frames RANGE --res W[xH] -o OUT.####.exr",
      "Writes position maps for compositing: per frame, a UV-space EXR whose texels hold the "
      "world position (R G B) interpolated from the mesh triangle under the texel centre, "
      "a coverage alpha A (1 on covered texels, 0 elsewhere, padding included) and, with "
      "--normals, area-weighted normals (layer N: N.R N.G N.B). Islands are padded by --padding "
      "texels: each padded texel copies its nearest covered texel (chessboard distance); "
      "texels beyond hold 0. Row 0 of the image is the top, v = 1; UVs outside [0, 1] are "
      "refused. --channels legacy writes the former names P.X P.Y P.Z, A, N.X N.Y N.Z.");
  parser.option("--mesh", "M.obj", "mesh with UVs (vertex order of the cache)", "", true)
      .option("--cache", "CACHE", "positions per frame (.pc2 or name.####.exr)", "", true)
      .option("--frames", "RANGE", "frames to write: 1001-1100, 1001-1100x2, 1001,1005", "", true)
      .option("--res", "W[xH]", "map size in texels, 1..16384 per side", "", true)
      .option("-o", "OUT.####.exr", "output EXR sequence (####, %04d or $F4)", "", true)
      .option("--padding", "N", "texels of dilation around each UV island (0..256)", "8")
      .option("--device", "SPEC", "auto, host, cpu, gpu, an index or a name substring", "auto")
      .option("--compression", "C", "zip, none, zips or piz (all lossless)", "zip")
      .option("--zip-encoder", "E",
              "who deflates zip and zips files (standard files either way): libdeflate, or "
              "openexr (OpenEXR's zlib writer, 2-4x the CPU: the bytes of earlier builds)",
              "libdeflate")
      .option("--fps", "X", "frames per second written to the EXR headers", "24")
      .option("--threads", "N", "files written at once (0 = all cores)", "0")
      .option("--chunk", "N", "frames per kernel launch (0 = as many as fit in 256 MiB)", "0")
      .option("--channels", "NAMING",
              "rgba (R G B, A, N.R N.G N.B) or legacy (P.X P.Y P.Z, A, N.X N.Y N.Z)", "rgba")
      .flag("--normals", "also write the normals N.R N.G N.B (FLOAT)")
      .flag("--half-normals", "write the normals as HALF (implies --normals)")
      .flag("--preview", "also write OUT.####.png, P mapped to colours, for eyeballing")
      .flag("--quiet", "no progress or per-frame lines")
      .epilog("Exit codes: 0 ok, 2 usage, 3 input, 4 output, 5 OpenCL device.");
  return parser;
}

PositionMapOptions positionMapOptionsFrom(const ArgParser& parser) {
  const auto [width, height] = parsePositionMapResolution(parser.get("--res"), "--res");
  PositionMapOptions options;
  options.width = width;
  options.height = height;
  options.padding = parser.getInt("--padding", 0);
  options.halfNormals = parser.has("--half-normals");
  options.normals = parser.has("--normals") || options.halfNormals;
  options.preview = parser.has("--preview");
  options.compression = parseExrCompression(parser.get("--compression"));
  options.zipEncoder = parseZipEncoder(parser.get("--zip-encoder"));
  options.framesPerSecond = parser.getDouble("--fps", 1e-3);
  options.threads = parser.getInt("--threads", 0);
  options.chunkSize = parser.getInt("--chunk", 0);
  options.channels = parsePositionMapChannels(parser.get("--channels"), "--channels");
  return options;
}

/// Writes every frame, with a progress bar and (not on a terminal) a line per frame unless
/// `quiet`.
PositionMapRunResult writeMapsWithProgress(PositionMapWriter& writer, const PointCacheReader& cache,
                                           const std::vector<int>& frames,
                                           const std::string& output, bool quiet) {
  std::unique_ptr<Progress> progress;
  if (!quiet) {
    progress = std::make_unique<Progress>("posmap", static_cast<long>(frames.size()));
  }
  const PositionMapRunResult result = writePositionMapSequence(
      writer, cache, frames, output, [&](int frame, const std::string& path) {
        if (progress) {
          if (!progress->isTerminal()) {
            std::cerr << "frame " << frame << " -> " << path << "\n";
          }
          progress->advance();
        }
      });
  if (progress) {
    progress->finish();
  }
  return result;
}

void printPosmapSummary(const PositionMapRunResult& result, const PositionMapOptions& options,
                        const std::string& device, const std::string& output,
                        const std::vector<int>& frames) {
  const double fps = result.totalSeconds > 0 ? result.written / result.totalSeconds : 0.0;
  std::cout << "wrote " << result.written << " position maps (" << options.width << "x"
            << options.height << ") in " << std::fixed << std::setprecision(3)
            << result.totalSeconds << " s, " << std::setprecision(1) << fps << " frames/s on "
            << device << " (read " << std::setprecision(3) << result.readSeconds << " s, evaluate "
            << result.evaluateSeconds << " s, write " << result.writeSeconds << " s)\n"
            << "outputs: " << absolute(output) << " (frames " << formatFrameRange(frames) << ")\n";
  if (options.preview) {
    std::cout << "previews: " << absolute(positionMapPreviewPath(output)) << "\n";
  }
}

}  // namespace

int runPosmap(const std::vector<std::string>& args) {
  ArgParser parser = posmapParser();
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const PositionMapOptions options = positionMapOptionsFrom(parser);
  const std::vector<int> frames = parseFrameRange(parser.get("--frames"));
  const std::string output = parser.get("-o");
  if (!hasFramePattern(output)) {
    DS_THROW(kUsage, "-o '", output, "' has no frame token; use e.g. maps/cloth.####.exr");
  }
  missingOutputFolders(expandFramePattern(output, frames.front()));  // created once inputs load
  const std::string cachePath = parser.get("--cache");
  std::vector<NamedPath> outputs = {{"-o", output, true}};
  if (options.preview) {
    const std::string previews = positionMapPreviewPath(output);
    if (!hasFramePattern(previews)) {
      DS_THROW(kUsage, "--preview: every frame's preview of -o '", output, "' would be '", previews,
               "' (the frame token is in the extension); put it before the extension");
    }
    outputs.push_back({"--preview", previews, true});
  }
  checkDistinctPaths(outputs, frames,
                     {{"--cache", cachePath, hasFramePattern(cachePath)},
                      {"--mesh", parser.get("--mesh"), false}});

  const std::string meshPath = parser.get("--mesh");
  const Mesh mesh = readObj(meshPath);
  // EXR caches carry a topology hash: it must be this mesh's.
  const auto cache = openPointCache(parser.get("--cache"), topologyHash(mesh));
  const bool quiet = parser.has("--quiet");
  createOutputFoldersFor({expandFramePattern(output, frames.front())}, quiet);
  const std::unique_ptr<Device> target = openCliDevice(parser.get("--device"), std::cerr);
  const std::string device = target->description();
  PositionMapWriter writer(mesh, options, target->makePositionMaps(), meshPath, &std::cerr);
  if (!quiet) {
    std::cerr << "position maps " << options.width << "x" << options.height << ", padding "
              << options.padding << ": " << writer.tables().coveredCount << " covered and "
              << writer.tables().paddedCount << " padded texels; " << frames.size() << " frames on "
              << device << "\n";
  }
  const PositionMapRunResult result = writeMapsWithProgress(writer, *cache, frames, output, quiet);
  printPosmapSummary(result, options, device, output, frames);
  return 0;
}

}  // namespace drivenshape::cli
