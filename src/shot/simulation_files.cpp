// SPDX-License-Identifier: Apache-2.0
// The simulation's files (drivenshape/simulation.h): the bake's frames checked for a plan, a
// window's simulated frames checked for reuse, the splice of point-cache EXR sequences into
// the output sequence, and the simulate report. What `drivenshape simulate` and a farm's splice
// task both call, so that both write the same bytes.

#include <drivenshape/simulation.h>

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/point_cache.h>

#include "atomic_file.h"
#include "hash.h"
#include "json_text.h"

namespace drivenshape {
namespace {

/// The EXR header attribute naming where a spliced frame comes from (frameSourceName).
constexpr const char* kAttrFrameSource = "dsSource";

/// Frames from..to of the sequence `pattern`, each of `vertexCount` vertices, frame-major.
std::vector<float> readSequenceFrames(const std::string& pattern, int from, int to, int vertexCount,
                                      const std::string& role) {
  const std::size_t values = 3 * static_cast<std::size_t>(vertexCount);
  std::vector<float> frames(static_cast<std::size_t>(to - from + 1) * values);
  std::vector<float> xyz;
  for (int f = from; f <= to; ++f) {
    const std::string path = expandFramePattern(pattern, f);
    try {
      readPointCacheExr(path, xyz, vertexCount);
    } catch (const Error& error) {
      DS_THROW(kInput, role, " frame ", f, ": ", error.what());
    }
    std::copy(xyz.begin(), xyz.end(),
              frames.begin() + static_cast<std::ptrdiff_t>((f - from) * values));
  }
  return frames;
}

}  // namespace

ExrPointCacheInfo checkSimulationBake(const SimulationPlan& plan, const std::string& bakePattern) {
  const ExrSequenceInfo sequence = checkPointCacheExrSequence(bakePattern);
  for (int f = plan.first; f <= plan.last; ++f) {
    if (!std::binary_search(sequence.frames.begin(), sequence.frames.end(), f)) {
      DS_THROW(kInput, "the bake '", bakePattern, "' has no frame ", f, " ('",
               expandFramePattern(bakePattern, f), "'; it holds ",
               formatFrameRange(sequence.frames), "); the report ", plan.report, " lists frames ",
               plan.first, "-", plan.last, ": give the bake the report is of");
    }
  }
  return sequence.first;
}

std::string bakeFramesStamp(const std::string& bakePattern, int first, int last) {
  Hasher hasher;
  for (int f = first; f <= last; ++f) {
    hasher.addString(readWholeFile(expandFramePattern(bakePattern, f), "bake frame"));
  }
  return hashToHex(hasher.value());
}

std::string simulatedWindowProblem(const SimulationWindow& window, const std::string& pattern,
                                   int vertexCount) {
  for (int f = window.warmupFrom; f <= window.to; ++f) {
    const std::string path = expandFramePattern(pattern, f);
    if (!isCompleteExr(path)) {
      return "frame " + std::to_string(f) + " ('" + path + "') is missing or incomplete";
    }
    try {
      const ExrPointCacheInfo info = readPointCacheExrInfo(path);
      if (info.vertexCount != vertexCount) {
        return "frame " + std::to_string(f) + " ('" + path + "') has " +
               std::to_string(info.vertexCount) + " vertices, the bake " +
               std::to_string(vertexCount);
      }
    } catch (const Error& error) {
      return "frame " + std::to_string(f) + ": " + error.what();
    }
  }
  return "";
}

SplicedShot spliceSimulationFiles(const SimulationPlan& plan, const std::string& bakePattern,
                                  const std::vector<std::string>& windowPatterns,
                                  const std::string& outputPattern) {
  const ExrPointCacheInfo bake = checkSimulationBake(plan, bakePattern);
  if (windowPatterns.size() != plan.windows.size()) {
    DS_THROW(kUsage, "splice: ", windowPatterns.size(), " simulated windows; the plan has ",
             plan.windows.size());
  }
  const std::vector<float> baked =
      readSequenceFrames(bakePattern, plan.first, plan.last, bake.vertexCount, "baked");
  std::vector<std::vector<float>> simulated;
  for (std::size_t w = 0; w < plan.windows.size(); ++w) {
    const SimulationWindow& window = plan.windows[w];
    simulated.push_back(readSequenceFrames(
        windowPatterns[w], window.warmupFrom, window.to, bake.vertexCount,
        "simulated window " + std::to_string(window.from) + "-" + std::to_string(window.to) + ":"));
  }
  SplicedShot shot = spliceSimulation(plan, bake.vertexCount, baked, simulated);
  ExrWriteOptions options;
  options.width = bake.width;
  options.compression = bake.compression;
  options.topologyHash = bake.topologyHash;
  options.framesPerSecond = bake.framesPerSecond > 0 ? bake.framesPerSecond : 24.0;
  const std::size_t values = 3 * static_cast<std::size_t>(bake.vertexCount);
  for (int f = plan.first; f <= plan.last; ++f) {
    const std::size_t i = static_cast<std::size_t>(f - plan.first);
    options.frame = f;
    options.stringAttributes = {{kAttrFrameSource, frameSourceName(shot.sources[i])}};
    writePointCacheExr(expandFramePattern(outputPattern, f), bake.vertexCount,
                       shot.positions.data() + i * values, nullptr, options);
  }
  return shot;
}

std::string simulateReportJson(const SimulationPlan& plan, const std::vector<FrameSource>& sources,
                               double seconds) {
  if (sources.size() != static_cast<std::size_t>(plan.last - plan.first + 1)) {
    DS_THROW(kUsage, "a simulate report of ", sources.size(), " frames for the plan's ", plan.first,
             "-", plan.last);
  }
  nlohmann::json frames = nlohmann::json::array();
  for (std::size_t i = 0; i < sources.size(); ++i) {
    frames.push_back(
        {{"frame", plan.first + static_cast<int>(i)}, {"source", frameSourceName(sources[i])}});
  }
  const nlohmann::json report{{"format", "drivenshape-simulate-report"},
                              {"version", 1},
                              {"plan", parseJsonText(simulationPlanJson(plan), "the plan")},
                              {"frames", frames},
                              {"seconds", seconds}};
  return jsonText(report, 2) + "\n";
}

}  // namespace drivenshape
