// SPDX-License-Identifier: Apache-2.0
// One frame's record as JSON (frame_record_json.h), the verdict over records, and merging the
// reports of parts of a shot (mergeBakeReports): what a report says of its frames, read back
// from EXRs by a resume and from chunk reports by a merge.

#include "frame_record_json.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <drivenshape/bake.h>
#include <drivenshape/coverage_check.h>
#include <drivenshape/error.h>
#include <drivenshape/frames.h>

#include "json_text.h"

namespace drivenshape {
namespace {

/// The weights as the report shows them: k numbers, or with regions one list of k per region.
nlohmann::json weightsJson(const std::vector<double>& weights, int shapeCount) {
  if (shapeCount <= 0 || weights.size() <= static_cast<std::size_t>(shapeCount)) {
    return weights;
  }
  nlohmann::json perRegion = nlohmann::json::array();
  for (std::size_t r = 0; r < weights.size(); r += shapeCount) {
    perRegion.push_back(std::vector<double>(weights.begin() + r, weights.begin() + r + shapeCount));
  }
  return perRegion;
}

/// A number of a record; null stands for a value JSON cannot hold (NaN, infinity).
double numberOf(const nlohmann::json& value, const std::string& where) {
  if (value.is_null()) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  if (!value.is_number()) {
    DS_THROW(kInput, where, " is ", jsonText(value), "; expected a number");
  }
  return value.get<double>();
}

std::vector<double> numbersOf(const nlohmann::json& value, const std::string& where) {
  if (!value.is_array()) {
    DS_THROW(kInput, where, " is ", jsonText(value), "; expected a list of numbers");
  }
  std::vector<double> out;
  for (std::size_t i = 0; i < value.size(); ++i) {
    out.push_back(numberOf(value[i], where + "[" + std::to_string(i) + "]"));
  }
  return out;
}

std::vector<int> integersOf(const nlohmann::json& value, const std::string& where) {
  if (!value.is_array()) {
    DS_THROW(kInput, where, " is ", jsonText(value), "; expected a list of whole numbers");
  }
  std::vector<int> out;
  for (std::size_t i = 0; i < value.size(); ++i) {
    out.push_back(jsonInt(value[i], where + "[" + std::to_string(i) + "]"));
  }
  return out;
}

/// The weights back, flat (region-major).
std::vector<double> weightsOf(const nlohmann::json& value, const std::string& where) {
  if (!value.is_array() || value.empty() || !value.front().is_array()) {
    return numbersOf(value, where);
  }
  std::vector<double> out;
  for (std::size_t r = 0; r < value.size(); ++r) {
    const std::vector<double> row = numbersOf(value[r], where + "[" + std::to_string(r) + "]");
    out.insert(out.end(), row.begin(), row.end());
  }
  return out;
}

nlohmann::json runsJson(const std::vector<SimulationRun>& runs) {
  nlohmann::json out = nlohmann::json::array();
  for (const SimulationRun& run : runs) {
    out.push_back({{"from", run.from}, {"to", run.to}, {"wanted", run.wanted}});
  }
  return out;
}

}  // namespace

nlohmann::json coverageJson(const std::vector<FrameRecord>& records, double tolerance, double level,
                            std::optional<int> shotStart) {
  std::vector<int> flagged;
  int checked = 0, first = 0;
  for (const FrameRecord& record : records) {
    if (record.flagged >= 0) {
      first = checked == 0 ? record.frame : std::min(first, record.frame);
      ++checked;
      if (record.flagged == 1) {
        flagged.push_back(record.frame);
      }
    }
  }
  if (checked == 0) {
    return nullptr;
  }
  std::sort(flagged.begin(), flagged.end());
  const double covered = 1.0 - static_cast<double>(flagged.size()) / checked;
  return {{"tolerance", tolerance},
          {"level", level},
          {"frames_checked", checked},
          {"covered_fraction", covered},
          {"simulate_frames", flagged.empty() ? std::string() : formatFrameRange(flagged)},
          {"simulate_runs", runsJson(simulationRuns(flagged, shotStart.value_or(first)))},
          {"run_up", kSimulationRunUp},
          {"verdict",
           flagged.empty() ? "DrivenShape is enough" : "simulate " + formatFrameRange(flagged)}};
}

nlohmann::json frameRecordJson(const FrameRecord& record, int shapeCount) {
  nlohmann::json entry{{"frame", record.frame},
                       {"relative_residual", record.relativeResidual},
                       {"kkt_residual", record.kktResidual},
                       {"iterations", record.iterations},
                       {"active_at_zero", record.atZero},
                       {"active_at_one", record.atOne},
                       {"weights", weightsJson(record.weights, shapeCount)}};
  if (record.directResidual >= 0.0) {
    entry["relative_residual_direct"] = record.directResidual;
  }
  if (!record.alignRotation.empty()) {
    entry["align_rotation"] = record.alignRotation;
    entry["align_translation"] = record.alignTranslation;
  }
  const std::pair<const char*, int> counts[] = {{"inside_before", record.insideBefore},
                                                {"inside_corrected", record.insideCorrected},
                                                {"inside_after", record.insideAfter},
                                                {"resolved", record.resolved},
                                                {"binding_switches", record.bindingSwitches}};
  for (const auto& [key, value] : counts) {
    if (value >= 0) {
      entry[key] = value;
    }
  }
  if (record.maxJump >= 0) {
    entry["max_jump"] = record.maxJump;
    entry["max_jump_vertex"] = record.maxJumpVertex;
  }
  if (record.predictedError >= 0) {
    entry["pose_distance"] = record.poseDistance;
    entry["predicted_error"] = record.predictedError;
    entry["error_bound"] = record.errorBound;
    entry["coverage"] = {{"flagged", record.flagged == 1}, {"score", record.errorBound}};
  }
  return entry;
}

FrameRecord frameRecordFromJson(const nlohmann::json& entry, const std::string& where) {
  if (!entry.is_object()) {
    DS_THROW(kInput, where, " is ", jsonText(entry).substr(0, 60), "; expected a frame record");
  }
  const auto field = [&](const char* key) -> const nlohmann::json& {
    if (!entry.contains(key)) {
      DS_THROW(kInput, where, " has no ", key);
    }
    return entry.at(key);
  };
  const auto at = [&](const char* key) { return where + " " + key; };
  FrameRecord record;
  record.frame = jsonInt(field("frame"), at("frame"));
  record.relativeResidual = numberOf(field("relative_residual"), at("relative_residual"));
  record.kktResidual = numberOf(field("kkt_residual"), at("kkt_residual"));
  record.iterations = jsonInt(field("iterations"), at("iterations"), 0);
  record.atZero = integersOf(field("active_at_zero"), at("active_at_zero"));
  record.atOne = integersOf(field("active_at_one"), at("active_at_one"));
  record.weights = weightsOf(field("weights"), at("weights"));
  if (entry.contains("relative_residual_direct")) {
    record.directResidual =
        numberOf(entry.at("relative_residual_direct"), at("relative_residual_direct"));
  }
  if (entry.contains("align_rotation")) {
    record.alignRotation = numbersOf(entry.at("align_rotation"), at("align_rotation"));
    record.alignTranslation = numbersOf(field("align_translation"), at("align_translation"));
  }
  const std::pair<const char*, int*> counts[] = {{"inside_before", &record.insideBefore},
                                                 {"inside_corrected", &record.insideCorrected},
                                                 {"inside_after", &record.insideAfter},
                                                 {"resolved", &record.resolved},
                                                 {"binding_switches", &record.bindingSwitches}};
  for (const auto& [key, value] : counts) {
    if (entry.contains(key)) {
      *value = jsonInt(entry.at(key), at(key), 0);
    }
  }
  if (entry.contains("max_jump")) {
    record.maxJump = numberOf(entry.at("max_jump"), at("max_jump"));
    record.maxJumpVertex = jsonInt(field("max_jump_vertex"), at("max_jump_vertex"), 0);
  }
  if (entry.contains("predicted_error")) {
    record.poseDistance = numberOf(field("pose_distance"), at("pose_distance"));
    record.predictedError = numberOf(entry.at("predicted_error"), at("predicted_error"));
    record.errorBound = numberOf(field("error_bound"), at("error_bound"));
    const nlohmann::json& coverage = field("coverage");
    if (!coverage.is_object() || !coverage.contains("flagged") ||
        !coverage.at("flagged").is_boolean()) {
      DS_THROW(kInput, where, " coverage is ", jsonText(coverage).substr(0, 60),
               "; expected {\"flagged\": true or false, ...}");
    }
    record.flagged = coverage.at("flagged").get<bool>() ? 1 : 0;
  }
  return record;
}

namespace {

/// A report's frames[] entry as a record: what frameRecordFromJson reads, or for a frame kept
/// by a resume up to 0.2.0 (`"skipped": true`, nothing else) a record without a prediction.
FrameRecord mergedRecord(const nlohmann::json& entry, const std::string& where) {
  if (entry.is_object() && entry.contains("skipped") && entry.at("skipped") == true) {
    if (!entry.contains("frame")) {
      DS_THROW(kInput, where, " is a kept frame without a \"frame\" number");
    }
    FrameRecord record;
    record.frame = jsonInt(entry.at("frame"), where + " frame");
    record.skipped = true;
    return record;
  }
  return frameRecordFromJson(entry, where);
}

/// `key` of `report` as an object (an empty one when missing), Error(kInput) otherwise.
const nlohmann::json& objectOf(const nlohmann::json& report, const char* key,
                               const std::string& source) {
  static const nlohmann::json empty = nlohmann::json::object();
  if (!report.contains(key)) {
    return empty;
  }
  if (!report.at(key).is_object()) {
    DS_THROW(kInput, source, ": ", key, " is ", jsonText(report.at(key)).substr(0, 60),
             "; expected an object");
  }
  return report.at(key);
}

/// Adds the numbers of `from` into `into`, key by key.
void addNumbers(nlohmann::json& into, const nlohmann::json& from) {
  for (const auto& [key, value] : from.items()) {
    if (value.is_number()) {
      into[key] = into.value(key, 0.0) + value.get<double>();
    }
  }
}

/// What the runs of the merged reports did: their counts summed, their rebaked frames.
void addRun(nlohmann::json& run, const nlohmann::json& report, const std::string& source) {
  const nlohmann::json& own = objectOf(report, "run", source);
  const auto count = [&](const char* key, const char* before) {
    const nlohmann::json& value =
        own.contains(key) ? own.at(key) : report.value(before, nlohmann::json(0));
    return jsonInt(value, source + ": run." + key, 0);
  };
  for (const auto& [key, before] : {std::pair{"baked", "baked"}, std::pair{"kept", "skipped"}}) {
    run[key] = run.value(key, 0) + count(key, before);
  }
  for (const char* key : {"stale_temp_files_removed", "closest_queries", "closest_cleared"}) {
    run[key] = run.value(key, 0LL) + (own.contains(key) ? count(key, key) : 0);
  }
  if (own.contains("rebaked") && own.at("rebaked").is_array()) {
    for (const nlohmann::json& entry : own.at("rebaked")) {
      run["rebaked"].push_back(entry);
    }
  }
}

}  // namespace

std::string mergeBakeReports(const std::vector<std::string>& texts,
                             const std::vector<std::string>& sources) {
  if (texts.empty() || texts.size() != sources.size()) {
    DS_THROW(kUsage, "mergeBakeReports: give one source name per report (", texts.size(),
             " reports, ", sources.size(), " names), at least one");
  }
  nlohmann::json merged;
  std::map<int, std::pair<nlohmann::json, FrameRecord>> frames;
  nlohmann::json run{{"rebaked", nlohmann::json::array()}}, seconds = nlohmann::json::object();
  std::vector<std::string> warnings;
  for (std::size_t i = 0; i < texts.size(); ++i) {
    const std::string& source = sources[i];
    const nlohmann::json report = parseJsonText(texts[i], source);
    if (!report.is_object() || !report.contains("frames") || !report.at("frames").is_array()) {
      DS_THROW(kInput, source, ": no \"frames\" list; expected a bake report (bake --report)");
    }
    if (i == 0) {
      merged = report;
    }
    for (const char* key : {"settings_hash", "database", "settings"}) {
      if (report.value(key, nlohmann::json()) != merged.value(key, nlohmann::json())) {
        DS_THROW(kInput, source, ": its ", key, " differs from that of ", sources[0],
                 "; merge only the reports of parts of one bake");
      }
    }
    const nlohmann::json& entries = report.at("frames");
    for (std::size_t e = 0; e < entries.size(); ++e) {
      const std::string where = source + ": frames[" + std::to_string(e) + "]";
      FrameRecord record = mergedRecord(entries[e], where);
      const auto known = frames.find(record.frame);
      if (known == frames.end() || known->second.second.skipped) {
        frames[record.frame] = {entries[e], std::move(record)};
      } else if (!record.skipped &&
                 frameRecordJson(record, 0) != frameRecordJson(known->second.second, 0)) {
        DS_THROW(kInput, where, ": frame ", record.frame,
                 " has another record than in an earlier report; merge the reports of one bake");
      }
    }
    for (const nlohmann::json& warning : report.value("warnings", nlohmann::json::array())) {
      const std::string text = warning.is_string() ? warning.get<std::string>() : jsonText(warning);
      if (std::find(warnings.begin(), warnings.end(), text) == warnings.end()) {
        warnings.push_back(text);
      }
    }
    addRun(run, report, source);
    addNumbers(seconds, objectOf(report, "seconds", source));
  }
  std::vector<FrameRecord> records;
  merged["frames"] = nlohmann::json::array();
  for (auto& [frame, entry] : frames) {
    merged["frames"].push_back(entry.first);
    records.push_back(entry.second);
  }
  merged.erase("baked");
  merged.erase("skipped");
  merged["run"] = run;
  merged["seconds"] = seconds;
  merged.erase("warnings");
  if (!warnings.empty()) {
    merged["warnings"] = warnings;
  }
  const nlohmann::json coverage = objectOf(merged, "coverage", sources[0]);
  merged.erase("coverage");
  if (!records.empty() && coverage.contains("tolerance")) {
    const std::string where = sources[0] + ": coverage.";
    const nlohmann::json verdict =
        coverageJson(records, numberOf(coverage.at("tolerance"), where + "tolerance"),
                     numberOf(coverage.value("level", nlohmann::json(0.0)), where + "level"),
                     records.front().frame);
    if (!verdict.is_null()) {
      merged["coverage"] = verdict;
    }
  }
  return jsonText(merged, 1) + "\n";
}

}  // namespace drivenshape
