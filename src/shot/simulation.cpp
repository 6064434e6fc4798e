// SPDX-License-Identifier: Apache-2.0
// Simulating what a bake's verdict flags (drivenshape/simulation.h): the plan of the windows
// from the report's flagged frames, its JSON, and the splice of the simulated frames into the
// baked ones.

#include <drivenshape/simulation.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <set>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/settings_table.h>

#include "atomic_file.h"
#include "json_text.h"

namespace drivenshape {
namespace {

constexpr const char* kPlanFormat = "drivenshape-simulation-plan";
constexpr int kPlanVersion = 1;

/// Every frame the report lists, ascending, and the flagged ones; Error(kInput) for a report
/// without frames or with a hole (the windows' warm-ups read the bake at any frame of the shot).
void planFrames(const BakeReportCoverage& report, std::vector<int>& frames,
                std::vector<int>& flagged) {
  for (const PredictedFrame& frame : report.predicted) {
    frames.push_back(frame.frame);
    if (frame.flagged) {
      flagged.push_back(frame.frame);
    }
  }
  frames.insert(frames.end(), report.unpredicted.begin(), report.unpredicted.end());
  std::sort(frames.begin(), frames.end());
  std::sort(flagged.begin(), flagged.end());
  if (frames.empty()) {
    DS_THROW(kInput, report.source, ": the report lists no frame; give the report of a bake");
  }
  for (std::size_t i = 1; i < frames.size(); ++i) {
    if (frames[i] != frames[i - 1] + 1) {
      DS_THROW(kInput, report.source, ": frame ", frames[i - 1] + 1, " is missing (the report has ",
               formatFrameRange(frames),
               "); a simulation needs every frame from the first to the last: give the report of "
               "one whole bake (farm chunks' reports merged)");
    }
  }
}

/// The plan's settings by the settings table's keys.
nlohmann::json planSettingsJson(const SimulationOptions& settings) {
  nlohmann::json out = nlohmann::json::object();
  for (const Setting* setting : settingsOfScope(SettingScope::kSimulate)) {
    out[setting->key] = std::visit([](const auto& v) { return nlohmann::json(v); },
                                   settingValue(*setting, settings));
  }
  return out;
}

/// A JSON value as a value of `setting`'s type; Error(kInput) naming `where` for another type.
SettingValue planSettingValue(const Setting& setting, const nlohmann::json& value,
                              const std::string& where) {
  switch (setting.type) {
    case SettingType::kBool:
      if (value.is_boolean()) {
        return value.get<bool>();
      }
      break;
    case SettingType::kInt:
      return jsonInt(value, where);
    case SettingType::kNumber:
      if (value.is_number()) {
        return value.get<double>();
      }
      break;
    default:
      if (value.is_string()) {
        return value.get<std::string>();
      }
  }
  DS_THROW(kInput, where, " is ", jsonText(value).substr(0, 60), "; expected a ",
           setting.type == SettingType::kBool ? "boolean" : "number");
}

SimulationOptions planSettingsOf(const nlohmann::json& json, const std::string& source) {
  if (!json.is_object()) {
    DS_THROW(kInput, source, ": settings is not an object");
  }
  SimulationOptions settings;
  for (const Setting* setting : settingsOfScope(SettingScope::kSimulate)) {
    const std::string where = source + ": settings." + setting->key;
    if (!json.contains(setting->key)) {
      DS_THROW(kInput, where, " is missing");
    }
    try {
      setSetting(*setting, settings, planSettingValue(*setting, json.at(setting->key), where));
    } catch (const Error& error) {
      // A value out of range is the file's fault here, not the command line's.
      DS_THROW(kInput, source, ": ", error.what());
    }
  }
  for (const auto& entry : json.items()) {
    const Setting* setting = findSettingByKey(entry.key());
    if (setting == nullptr || setting->scope != SettingScope::kSimulate) {
      DS_THROW(kInput, source, ": settings has '", entry.key(), "', not a simulation setting");
    }
  }
  return settings;
}

const nlohmann::json& planField(const nlohmann::json& object, const char* key,
                                const std::string& where) {
  if (!object.is_object() || !object.contains(key)) {
    DS_THROW(kInput, where, " has no \"", key, "\"");
  }
  return object.at(key);
}

/// Whether `window` lies within frames ..`last`, starting at `after` or later (the shot's first
/// frame, or two frames after the window before: windows never touch).
bool windowFits(const SimulationWindow& window, long long after, int last) {
  return window.warmupFrom >= after && window.from >= window.warmupFrom &&
         window.to >= window.from && window.to <= last;
}

/// The windows of a plan, checked against its frames and each other.
std::vector<SimulationWindow> planWindowsOf(const nlohmann::json& json, int first, int last,
                                            const std::string& source) {
  if (!json.is_array()) {
    DS_THROW(kInput, source, ": windows is not an array");
  }
  std::vector<SimulationWindow> windows;
  for (std::size_t i = 0; i < json.size(); ++i) {
    const std::string where = source + ": windows[" + std::to_string(i) + "]";
    SimulationWindow window;
    window.warmupFrom = jsonInt(planField(json[i], "warmup_from", where), where + " warmup_from");
    window.from = jsonInt(planField(json[i], "from", where), where + " from");
    window.to = jsonInt(planField(json[i], "to", where), where + " to");
    const long long after = windows.empty() ? first : windows.back().to + 2LL;
    if (!windowFits(window, after, last)) {
      DS_THROW(kInput, where, " (", window.warmupFrom, ", ", window.from, "-", window.to,
               ") is not a window of frames ", first, "-", last,
               " after the one before: expected warmup_from <= from <= to, in frame order, "
               "apart from each other");
    }
    windows.push_back(window);
  }
  return windows;
}

/// Refuses an array of `what` whose size is not `expected`.
void checkSpliceSize(std::size_t size, std::size_t expected, const std::string& what) {
  if (size != expected) {
    DS_THROW(kUsage, "splice: ", what, " holds ", size, " floats; the plan needs ", expected);
  }
}

/// out = b + weight (s - b), per coordinate, in double.
void blendSpliceFrame(const float* b, const float* s, double weight, std::size_t values,
                      float* out) {
  for (std::size_t i = 0; i < values; ++i) {
    const double base = b[i];
    out[i] = static_cast<float>(base + weight * (static_cast<double>(s[i]) - base));
  }
}

/// The frames a window's seam fades over: min(seam, its warm-up).
int seamFrames(const SimulationWindow& window, const SimulationOptions& settings) {
  return std::min(settings.seam, window.from - window.warmupFrom);
}

void checkSimulatedFinite(const std::vector<float>& frames, std::size_t w,
                          const SimulationWindow& window, int vertexCount) {
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (!std::isfinite(frames[i])) {
      const std::size_t perFrame = 3 * static_cast<std::size_t>(vertexCount);
      DS_THROW(kNumerical, "splice: window ", w, " (frames ", window.warmupFrom, "-", window.to,
               ") has a position that is not finite at frame ",
               window.warmupFrom + static_cast<long long>(i / perFrame), ", vertex ",
               (i % perFrame) / 3);
    }
  }
}

}  // namespace

int SimulationPlan::simulatedFrames() const {
  int frames = 0;
  for (const SimulationWindow& window : windows) {
    frames += window.to - window.warmupFrom + 1;
  }
  return frames;
}

SimulationPlan planSimulation(const BakeReportCoverage& report, const SimulationOptions& settings) {
  checkSimulationSettings(settings);
  std::vector<int> frames, flagged;
  planFrames(report, frames, flagged);
  if (report.predicted.empty()) {
    DS_THROW(kInput, report.source,
             ": no frame has a predicted error, so none is flagged for simulation; bake with the "
             "pose model (the default --weights auto on a database built with --model pose) and "
             "--report");
  }
  SimulationPlan plan;
  plan.report = report.source;
  plan.settings = settings;
  plan.first = frames.front();
  plan.last = frames.back();
  if (settings.fromStart && !flagged.empty()) {
    plan.windows.push_back(
        {plan.first, flagged.front(), flagged.back(), static_cast<int>(flagged.size())});
  } else {
    plan.windows = simulationWindows(flagged, plan.first, settings.warmup, settings.mergeGap);
  }
  return plan;
}

std::string simulationPlanJson(const SimulationPlan& plan) {
  nlohmann::json windows = nlohmann::json::array();
  for (const SimulationWindow& window : plan.windows) {
    windows.push_back(
        {{"warmup_from", window.warmupFrom}, {"from", window.from}, {"to", window.to}});
  }
  const nlohmann::json json{{"format", kPlanFormat},
                            {"version", kPlanVersion},
                            {"report", plan.report},
                            {"settings", planSettingsJson(plan.settings)},
                            {"frames", {{"first", plan.first}, {"last", plan.last}}},
                            {"windows", windows},
                            {"simulated_frames", plan.simulatedFrames()}};
  return jsonText(json, 2) + "\n";
}

SimulationPlan parseSimulationPlan(const std::string& text, const std::string& source) {
  const nlohmann::json json = parseJsonText(text, source);
  if (!json.is_object() || !json.contains("format") || json.at("format") != kPlanFormat) {
    DS_THROW(kInput, source, ": not a simulation plan (no \"format\": \"", kPlanFormat, "\")");
  }
  const int version = jsonInt(planField(json, "version", source), source + ": version");
  if (version != kPlanVersion) {
    DS_THROW(kInput, source, ": a simulation plan of version ", version,
             "; this drivenshape reads ", kPlanVersion);
  }
  SimulationPlan plan;
  const nlohmann::json& report = planField(json, "report", source);
  if (!report.is_string()) {
    DS_THROW(kInput, source, ": report is ", jsonText(report).substr(0, 60), "; expected a path");
  }
  plan.report = report.get<std::string>();
  plan.settings = planSettingsOf(planField(json, "settings", source), source);
  const nlohmann::json& frames = planField(json, "frames", source);
  plan.first = jsonInt(planField(frames, "first", source + ": frames"), source + ": frames.first");
  plan.last =
      jsonInt(planField(frames, "last", source + ": frames"), source + ": frames.last", plan.first);
  plan.windows = planWindowsOf(planField(json, "windows", source), plan.first, plan.last, source);
  const int simulated =
      jsonInt(planField(json, "simulated_frames", source), source + ": simulated_frames", 0);
  if (simulated != plan.simulatedFrames()) {
    DS_THROW(kInput, source, ": simulated_frames is ", simulated, " but its windows run ",
             plan.simulatedFrames(), " frames");
  }
  return plan;
}

SimulationPlan readSimulationPlan(const std::string& path) {
  return parseSimulationPlan(readWholeFile(path, "simulation plan"), path);
}

const char* frameSourceName(FrameSource source) {
  switch (source) {
    case FrameSource::kBaked:
      return "baked";
    case FrameSource::kSimulated:
      return "simulated";
    case FrameSource::kBlended:
      return "blended";
  }
  return "?";
}

SplicedShot spliceSimulation(const SimulationPlan& plan, int vertexCount,
                             const std::vector<float>& baked,
                             const std::vector<std::vector<float>>& simulated) {
  if (vertexCount < 1 || plan.last < plan.first) {
    DS_THROW(kUsage, "splice: ", vertexCount, " vertices over frames ", plan.first, "-", plan.last,
             "; expected at least 1 vertex and 1 frame");
  }
  const std::size_t values = 3 * static_cast<std::size_t>(vertexCount);
  const auto row = [&](int frame) {
    return static_cast<std::size_t>(static_cast<long long>(frame) - plan.first) * values;
  };
  checkSpliceSize(baked.size(), row(plan.last + 1), "the baked frames");
  if (simulated.size() != plan.windows.size()) {
    DS_THROW(kUsage, "splice: ", simulated.size(), " simulated windows; the plan has ",
             plan.windows.size());
  }
  SplicedShot shot{baked, std::vector<FrameSource>(row(plan.last + 1) / values)};
  for (std::size_t w = 0; w < plan.windows.size(); ++w) {
    const SimulationWindow& window = plan.windows[w];
    const long long after = w == 0 ? plan.first : plan.windows[w - 1].to + 2LL;
    if (!windowFits(window, after, plan.last)) {
      DS_THROW(kUsage, "splice: window ", w, " (", window.warmupFrom, ", ", window.from, "-",
               window.to, ") is not a window of the plan's frames ", plan.first, "-", plan.last,
               " apart from the one before");
    }
    const std::vector<float>& frames = simulated[w];
    checkSpliceSize(frames.size(),
                    (static_cast<std::size_t>(window.to - window.warmupFrom) + 1) * values,
                    "simulated window " + std::to_string(w) + " (frames " +
                        std::to_string(window.warmupFrom) + "-" + std::to_string(window.to) + ")");
    checkSimulatedFinite(frames, w, window, vertexCount);
    const auto sim = [&](int frame) {
      return frames.data() + static_cast<std::size_t>(frame - window.warmupFrom) * values;
    };
    const auto set = [&](int frame, FrameSource source) {
      shot.sources[row(frame) / values] = source;
      return shot.positions.data() + row(frame);
    };
    for (int f = window.from; f <= window.to; ++f) {
      std::copy(sim(f), sim(f) + values, set(f, FrameSource::kSimulated));
    }
    const int seam = seamFrames(window, plan.settings);
    for (int k = 1; k <= seam; ++k) {
      const int f = window.from - seam - 1 + k;
      blendSpliceFrame(baked.data() + row(f), sim(f), static_cast<double>(k) / (seam + 1), values,
                       set(f, FrameSource::kBlended));
    }
    // The residual at `to`, carried until the next window's seam or the shot's end.
    const int stop =
        w + 1 < plan.windows.size()
            ? plan.windows[w + 1].from - seamFrames(plan.windows[w + 1], plan.settings) - 1
            : plan.last;
    const float* bakeTo = baked.data() + row(window.to);
    const int carry = plan.settings.carry;
    for (int k = 1; k <= carry && window.to + k <= stop; ++k) {
      const int f = window.to + k;
      const double fade = 1.0 - static_cast<double>(k) / (carry + 1);
      const float* b = baked.data() + row(f);
      float* out = set(f, FrameSource::kBlended);
      for (std::size_t i = 0; i < values; ++i) {
        const double residual = static_cast<double>(sim(window.to)[i]) - bakeTo[i];
        out[i] = static_cast<float>(static_cast<double>(b[i]) + fade * residual);
      }
    }
  }
  return shot;
}

}  // namespace drivenshape
