// SPDX-License-Identifier: Apache-2.0
// The coverage part of a bake report (src/shot/coverage_check.cpp, `eval --report`): a report
// that parses holds finite predictions >= 0 on distinct frames and a tolerance >= 0 when it
// predicts; matched to a fixed evaluation of frames 1-6, every evaluated frame is predicted,
// missing or unpredicted, and the statistics stay in their ranges. And the frame records
// (src/shot/frame_record_json.cpp: what a resume reads back from each EXR's dsRecord, what a
// merge of chunk reports reads): a report that merges gives a report whose frames ascend, each
// once, and which merges into itself byte for byte; each record read back writes the same JSON.

#include <cmath>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include <drivenshape/bake.h>
#include <drivenshape/coverage_check.h>

#include "frame_record_json.h"
#include "fuzz_support.h"
#include "json_text.h"

namespace ds = drivenshape;

namespace {

/// Frames 1-6 of a 12-vertex cloth (the report seeds state 12), with two tied errors.
ds::ShotEvaluation fixedEvaluation() {
  ds::ShotEvaluation e;
  e.vertexCount = 12;
  e.bake.source = "bake.####.exr";
  const double errors[] = {0.3, 0.1, 0.4, 0.1, 0.5, 0.9};
  for (int f = 1; f <= 6; ++f) {
    e.frames.push_back(f);
    ds::ClothFrameMetrics m;
    m.frame = f;
    m.error.frame = f;
    m.error.mean = errors[f - 1];
    e.bake.frames.push_back(m);
  }
  return e;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  static const ds::ShotEvaluation evaluation = fixedEvaluation();
  ds::fuzz::expectOnlyErrors("parseBakeReportCoverage", [&] {
    const ds::BakeReportCoverage report = ds::parseBakeReportCoverage(text, "fuzz.json");
    const char* reader = "parseBakeReportCoverage";
    std::set<int> frames(report.unpredicted.begin(), report.unpredicted.end());
    ds::fuzz::require(frames.size() == report.unpredicted.size(), reader, "a frame twice");
    for (const ds::PredictedFrame& p : report.predicted) {
      ds::fuzz::require(std::isfinite(p.predictedError) && p.predictedError >= 0.0, reader,
                        "a prediction that is not finite or is negative");
      ds::fuzz::require(frames.insert(p.frame).second, reader, "a frame twice");
    }
    ds::fuzz::require(
        report.predicted.empty() || (std::isfinite(report.tolerance) && report.tolerance >= 0.0),
        reader, "predictions without a tolerance >= 0");

    const ds::CoverageCheck c = ds::checkCoverage(report, evaluation);
    const char* check = "checkCoverage";
    ds::fuzz::require(!c.frames.empty(), check, "returned without a matched frame");
    ds::fuzz::require(c.frames.size() + c.missing + c.unpredicted == evaluation.frames.size(),
                      check, "evaluated frames lost or counted twice");
    ds::fuzz::require(c.enough + c.flagged == static_cast<int>(c.frames.size()), check,
                      "enough + flagged is not the matched frames");
    ds::fuzz::require(c.coveredFraction >= 0.0 && c.coveredFraction <= 1.0, check,
                      "covered fraction outside [0, 1]");
    ds::fuzz::require(!c.spearman || (*c.spearman >= -1.0 && *c.spearman <= 1.0), check,
                      "Spearman outside [-1, 1]");
    ds::fuzz::require(c.verdictHolds.has_value() == (c.enough > 0), check,
                      "a verdict without enough frames, or none with them");
  });
  ds::fuzz::expectOnlyErrors("mergeBakeReports", [&] {
    const char* reader = "mergeBakeReports";
    const std::string merged = ds::mergeBakeReports({text, text}, {"a.json", "b.json"});
    ds::fuzz::require(ds::mergeBakeReports({merged}, {"merged.json"}) == merged, reader,
                      "a merged report that does not merge into itself");
    const nlohmann::json report = ds::parseJsonText(merged, "merged.json");
    int previous = 0;
    bool first = true;
    for (const nlohmann::json& entry : report.at("frames")) {
      const int frame = entry.at("frame").get<int>();
      ds::fuzz::require(first || frame > previous, reader, "frames not ascending, or twice");
      first = false;
      previous = frame;
      if (entry.contains("skipped") && entry.at("skipped") == true) {
        continue;
      }
      const nlohmann::json again = ds::frameRecordJson(ds::frameRecordFromJson(entry, "f"), 0);
      ds::fuzz::require(ds::jsonText(again) == ds::jsonText(ds::frameRecordJson(
                                                   ds::frameRecordFromJson(again, "g"), 0)),
                        "frameRecordFromJson", "a record that does not read back as written");
    }
  });
  return 0;
}
