// SPDX-License-Identifier: Apache-2.0
// The bake report's coverage verdict against a truth (drivenshape/coverage_check.h): reading
// the predictions from the report, matching them to eval's measured errors, and the statistics.

#include <drivenshape/coverage_check.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <set>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>

#include "atomic_file.h"

#include "json_text.h"

namespace drivenshape {
namespace {

/// `coverage.flagged` of a frame entry: a boolean, 0 or 1 (or `coverage` itself a boolean).
bool flaggedOf(const nlohmann::json& entry, const std::string& where) {
  const nlohmann::json* flag = nullptr;
  if (entry.contains("coverage")) {
    const nlohmann::json& coverage = entry.at("coverage");
    if (coverage.is_boolean()) {
      flag = &coverage;
    } else if (coverage.is_object() && coverage.contains("flagged")) {
      flag = &coverage.at("flagged");
    }
  }
  if (flag == nullptr) {
    DS_THROW(kInput, where, " has a predicted_error but no coverage.flagged");
  }
  if (flag->is_boolean()) {
    return flag->get<bool>();
  }
  return jsonInt(*flag, where + " coverage.flagged", 0, 1) == 1;
}

double meanOf(const std::vector<double>& values) {
  return std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
}

}  // namespace

BakeReportCoverage parseBakeReportCoverage(const std::string& text, const std::string& source) {
  const nlohmann::json report = parseJsonText(text, source);
  if (!report.is_object() || !report.contains("frames") || !report.at("frames").is_array()) {
    DS_THROW(kInput, source,
             ": no \"frames\" array; expected the JSON report of a bake (bake --report)");
  }
  BakeReportCoverage out;
  out.source = source;
  const nlohmann::json& frames = report.at("frames");
  std::set<int> seen;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const nlohmann::json& entry = frames[i];
    const std::string at = source + ": frames[" + std::to_string(i) + "]";
    if (!entry.is_object() || !entry.contains("frame")) {
      DS_THROW(kInput, at, " is not an object with a \"frame\"");
    }
    const int frame = jsonInt(entry.at("frame"), at + " frame");
    const std::string where = source + ": frame " + std::to_string(frame);
    if (!seen.insert(frame).second) {
      DS_THROW(kInput, where,
               " is listed twice; give the report of one bake (merge farm chunks "
               "by evaluating each chunk with its own report)");
    }
    if (!entry.contains("predicted_error")) {
      out.unpredicted.push_back(frame);
      continue;
    }
    const nlohmann::json& predicted = entry.at("predicted_error");
    if (!predicted.is_number() || !std::isfinite(predicted.get<double>()) ||
        predicted.get<double>() < 0.0) {
      DS_THROW(kInput, where, ": predicted_error is ", jsonText(predicted),
               "; expected a finite number >= 0");
    }
    out.predicted.push_back({frame, predicted.get<double>(), flaggedOf(entry, where)});
  }
  if (report.contains("database")) {
    const nlohmann::json& database = report.at("database");
    if (!database.is_object()) {
      DS_THROW(kInput, source, ": database is ", jsonText(database),
               "; expected the object a bake writes (content_hash, driven_vertices, ...)");
    }
    if (database.contains("driven_vertices")) {
      out.clothVertices =
          jsonInt(database.at("driven_vertices"), source + ": database.driven_vertices", 1);
    }
  }
  if (report.contains("settings") && report.at("settings").is_object() &&
      report.at("settings").contains("weights") &&
      report.at("settings").at("weights").is_string()) {
    out.weights = report.at("settings").at("weights").get<std::string>();
  }
  if (!out.predicted.empty()) {
    const nlohmann::json* tolerance = nullptr;
    if (report.contains("coverage") && report.at("coverage").is_object() &&
        report.at("coverage").contains("tolerance")) {
      tolerance = &report.at("coverage").at("tolerance");
    }
    if (tolerance == nullptr || !tolerance->is_number() ||
        !std::isfinite(tolerance->get<double>()) || tolerance->get<double>() < 0.0) {
      DS_THROW(kInput, source,
               ": frames have a predicted_error but the shot's coverage.tolerance is ",
               tolerance == nullptr ? std::string("missing") : jsonText(*tolerance),
               "; expected a finite number >= 0");
    }
    out.tolerance = tolerance->get<double>();
    const nlohmann::json& coverage = report.at("coverage");
    if (coverage.contains("level")) {
      const nlohmann::json& level = coverage.at("level");
      if (!level.is_number() || !(level.get<double>() >= 0.0 && level.get<double>() < 1.0)) {
        DS_THROW(kInput, source, ": coverage.level is ", jsonText(level),
                 "; expected a number from 0 to below 1");
      }
      out.level = level.get<double>();
    }
  }
  return out;
}

BakeReportCoverage readBakeReportCoverage(const std::string& path) {
  return parseBakeReportCoverage(readWholeFile(path, "bake report"), path);
}

bool verdictHolds(int enough, int missed, double enoughTrueError, double tolerance, double level) {
  if (enough < 1 || missed < 0 || missed > enough || !(level >= 0.0 && level < 1.0)) {
    DS_THROW(kInput,
             "a verdict is judged on at least 1 frame called enough, with 0 to that many "
             "missed, at a level from 0 to below 1 (got ",
             enough, " frames, ", missed, " missed, level ", level, ")");
  }
  if (level > 0.0) {
    return static_cast<double>(enough - missed) / enough >= level;
  }
  return enoughTrueError <= tolerance;
}

CoverageCheck checkCoverage(const BakeReportCoverage& report, const ShotEvaluation& evaluation) {
  if (report.clothVertices >= 0 && report.clothVertices != evaluation.vertexCount) {
    DS_THROW(kInput, report.source, ": the report is of a bake of ", report.clothVertices,
             " cloth vertices, the bake '", evaluation.bake.source, "' has ",
             evaluation.vertexCount, "; pass the report of this bake");
  }
  if (report.predicted.empty()) {
    DS_THROW(kInput, report.source, ": no frame has a predicted error",
             report.weights.empty() ? std::string() : " (its weights are '" + report.weights + "')",
             "; the prediction comes from the pose model: bake with it (the default --weights "
             "auto on a database built with --model pose) and --report, then eval again");
  }
  std::map<int, const PredictedFrame*> byFrame;
  for (const PredictedFrame& p : report.predicted) {
    byFrame[p.frame] = &p;
  }
  const std::set<int> unpredicted(report.unpredicted.begin(), report.unpredicted.end());
  CoverageCheck check;
  check.tolerance = report.tolerance;
  check.level = report.level;
  for (const ClothFrameMetrics& m : evaluation.bake.frames) {
    const auto found = byFrame.find(m.frame);
    if (found == byFrame.end()) {
      ++(unpredicted.count(m.frame) != 0 ? check.unpredicted : check.missing);
      continue;
    }
    check.frames.push_back(
        {m.frame, found->second->predictedError, found->second->flagged, m.error.mean});
  }
  if (check.frames.empty()) {
    std::vector<int> predictedFrames;
    for (const PredictedFrame& p : report.predicted) {
      predictedFrames.push_back(p.frame);
    }
    std::sort(predictedFrames.begin(), predictedFrames.end());
    DS_THROW(kInput, report.source, ": predicts frames ", formatFrameRange(predictedFrames),
             " but none of the evaluated frames (", formatFrameRange(evaluation.frames),
             "); pass the frames of this bake to --frames");
  }
  std::vector<double> predicted, truth, enough, flagged;
  double predictedSum = 0.0;
  const CoverageFrame* worst = &check.frames.front();
  for (const CoverageFrame& f : check.frames) {
    predictedSum += f.predictedError;
    worst = f.predictedError > worst->predictedError ? &f : worst;
    predicted.push_back(f.predictedError);
    truth.push_back(f.trueError);
    (f.flagged ? flagged : enough).push_back(f.trueError);
    if (!f.flagged && f.trueError > check.tolerance) {
      ++check.missed;
    }
  }
  check.predictedMean = predictedSum / static_cast<double>(check.frames.size());
  check.predictedMax = worst->predictedError;
  check.predictedMaxFrame = worst->frame;
  check.spearman = spearmanCorrelation(predicted, truth);
  check.enough = static_cast<int>(enough.size());
  check.flagged = static_cast<int>(flagged.size());
  check.coveredFraction =
      static_cast<double>(enough.size()) / static_cast<double>(check.frames.size());
  if (!enough.empty()) {
    check.enoughTrueError = meanOf(enough);
    check.withinShare = static_cast<double>(check.enough - check.missed) / check.enough;
    check.verdictHolds = verdictHolds(check.enough, check.missed, *check.enoughTrueError,
                                      check.tolerance, check.level);
  }
  if (!flagged.empty()) {
    check.flaggedTrueError = meanOf(flagged);
  }
  return check;
}

std::vector<SimulationWindow> simulationWindows(const std::vector<int>& flagged, int first,
                                                int warmup, int mergeGap) {
  if (warmup < 0 || mergeGap < 0) {
    DS_THROW(kInternal, "simulation windows with a warm-up of ", warmup, " and a merge gap of ",
             mergeGap, " frames");
  }
  std::vector<SimulationWindow> windows;
  for (std::size_t i = 0; i < flagged.size();) {
    std::size_t j = i;  // [i, j]: flagged frames at most mergeGap unflagged frames apart
    while (j + 1 < flagged.size() && flagged[j + 1] > flagged[j] &&
           static_cast<long long>(flagged[j + 1]) - flagged[j] - 1 <= mergeGap) {
      ++j;
    }
    if (j + 1 < flagged.size() && flagged[j + 1] <= flagged[j]) {
      DS_THROW(kInternal, "simulation windows of frames that are not ascending and distinct (",
               flagged[j], " then ", flagged[j + 1], ")");
    }
    const int warmupFrom =
        static_cast<int>(std::max<long long>(first, static_cast<long long>(flagged[i]) - warmup));
    const int wanted = static_cast<int>(j - i + 1);
    if (!windows.empty() && warmupFrom <= static_cast<long long>(windows.back().to) + 1) {
      windows.back().to = flagged[j];
      windows.back().wanted += wanted;
    } else {
      windows.push_back({warmupFrom, flagged[i], flagged[j], wanted});
    }
    i = j + 1;
  }
  return windows;
}

std::vector<SimulationRun> simulationRuns(const std::vector<int>& flagged, int first, int runUp) {
  std::vector<SimulationRun> runs;
  for (const SimulationWindow& window : simulationWindows(flagged, first, runUp, 0)) {
    runs.push_back({window.warmupFrom, window.to, window.wanted});
  }
  return runs;
}

std::vector<double> averageRanks(const std::vector<double>& values) {
  for (double v : values) {
    if (!std::isfinite(v)) {
      DS_THROW(kNumerical, "a rank correlation over a value that is not finite (", v, ")");
    }
  }
  std::vector<std::size_t> order(values.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return values[a] < values[b]; });
  std::vector<double> ranks(values.size());
  for (std::size_t first = 0; first < order.size();) {
    std::size_t last = first;  // the run [first, last] of equal values
    while (last + 1 < order.size() && values[order[last + 1]] == values[order[first]]) {
      ++last;
    }
    // Positions first..last (0-based) are ranks first+1..last+1: each gets their mean.
    const double rank = 0.5 * static_cast<double>(first + last) + 1.0;
    for (std::size_t i = first; i <= last; ++i) {
      ranks[order[i]] = rank;
    }
    first = last + 1;
  }
  return ranks;
}

std::optional<double> spearmanCorrelation(const std::vector<double>& x,
                                          const std::vector<double>& y) {
  if (x.size() != y.size()) {
    DS_THROW(kInternal, "rank correlation of ", x.size(), " values against ", y.size());
  }
  const std::vector<double> rx = averageRanks(x), ry = averageRanks(y);
  if (x.size() < 2) {
    return std::nullopt;
  }
  const double mean = 0.5 * static_cast<double>(x.size() + 1);  // of ranks 1..n, ties or not
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  for (std::size_t i = 0; i < rx.size(); ++i) {
    sxy += (rx[i] - mean) * (ry[i] - mean);
    sxx += (rx[i] - mean) * (rx[i] - mean);
    syy += (ry[i] - mean) * (ry[i] - mean);
  }
  if (sxx == 0.0 || syy == 0.0) {
    return std::nullopt;
  }
  return std::clamp(sxy / std::sqrt(sxx * syy), -1.0, 1.0);
}

}  // namespace drivenshape
