// SPDX-License-Identifier: Apache-2.0
// The bake report (docs/schemas/bake_report.schema.json): the shot's settings, every frame's
// record and the coverage verdict over the shot, plus `run` and `seconds`, what the run that
// wrote it did. Frame records are also what each baked EXR carries (frame_record_json.h).

#include <drivenshape/bake.h>

#include "frame_record_json.h"

#include <algorithm>
#include <optional>
#include <string>
#include <vector>

#include <drivenshape/settings_table.h>
#include <drivenshape/version.h>

#include "hash.h"
#include "json_text.h"

namespace drivenshape {
namespace {

/// What this run did: the frames it baked and kept, why it baked some again, the temporary
/// files it removed and the closest-point work (which depends on the batching).
nlohmann::json runJson(const BakeResult& result) {
  nlohmann::json rebaked = nlohmann::json::array();
  long long queries = 0, cleared = 0;
  for (const FrameRecord& record : result.frames) {
    if (!record.rebakeReason.empty()) {
      rebaked.push_back({{"frame", record.frame}, {"because", record.rebakeReason}});
    }
    queries += record.closestQueries;
    cleared += record.closestCleared;
  }
  return {{"baked", result.baked},      {"kept", result.skipped},
          {"rebaked", rebaked},         {"stale_temp_files_removed", result.staleTempFilesRemoved},
          {"closest_queries", queries}, {"closest_cleared", cleared}};
}

nlohmann::json secondsJson(const StageTimes& times) {
  nlohmann::json seconds{
      {"read", times.read},          {"setup", times.setup},          {"write", times.write},
      {"read_wait", times.readWait}, {"write_wait", times.writeWait}, {"total", times.total}};
  for (const char* stage : {"align", "project", "weights", "blend", "correct", "strain", "resolve",
                            "settle", "layers", "audit"}) {
    seconds[stage] = 0.0;
  }
  for (const auto& [stage, value] : times.stages) {
    seconds[stage] = value;
  }
  return seconds;
}

}  // namespace

std::string bakeReportJson(const Database& db, const std::string& driverPath,
                           const BakeOptions& options, const Evaluator& evaluator,
                           const BakeResult& result) {
  nlohmann::json settings = parseJsonText(evaluator.describeSettings(), "the evaluator settings");
  settings.update(parseJsonText(describeBakeSettings(options), "the bake settings"));
  settings["untrusted_driver"] = !options.untrustedDriver.empty();
  nlohmann::json frames = nlohmann::json::array();
  for (const FrameRecord& record : result.frames) {
    nlohmann::json entry = frameRecordJson(record, db.shapeCount());
    entry["output"] = record.output;
    frames.push_back(std::move(entry));
  }
  nlohmann::json report{
      {"tool", "drivenshape"},
      {"tool_version", kVersion},
      {"device", result.device},
      {"database",
       {{"content_hash", hashToHex(db.contentHash())},
        {"shape_count", db.shapeCount()},
        {"driven_vertices", db.drivenVertexCount()},
        {"frames", db.frames}}},
      {"driver_cache", driverPath},
      {"output", options.outputPattern},
      {"settings_hash", hashToHex(result.settingsHash)},
      {"settings", settings},
      {"run", runJson(result)},
      {"seconds", secondsJson(result.times)},
      {"frames", frames},
  };
  if (!result.warnings.empty()) {
    report["warnings"] = result.warnings;
  }
  std::optional<int> shotStart;
  if (!options.shotFrames.empty()) {
    shotStart = *std::min_element(options.shotFrames.begin(), options.shotFrames.end());
  }
  const nlohmann::json coverage = coverageJson(result.frames, evaluator.coverageTolerance(),
                                               db.poseModel.verdictLevel, shotStart);
  if (!coverage.is_null()) {
    report["coverage"] = coverage;
  }
  return jsonText(report, 1) + "\n";
}

std::string coverageVerdictJson(const std::vector<FrameRecord>& records, double tolerance,
                                double level) {
  return jsonText(coverageJson(records, tolerance, level, std::nullopt));
}

}  // namespace drivenshape
