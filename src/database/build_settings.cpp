// SPDX-License-Identifier: Apache-2.0
// The table of `db build` settings (drivenshape/build_settings.h).

#include <drivenshape/build_settings.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include <drivenshape/error.h>

namespace drivenshape {
namespace {

/// Error(kUsage): the setting, what it takes, and the text it got.
[[noreturn]] void refuse(const BuildSetting& self, const char* takes, const std::string& text) {
  DS_THROW(kUsage, self.flag, " (", self.key, ") takes ", takes, " (got '", text, "')");
}

/// A whole number in [minimum, maximum] written in decimal digits, else refused.
int wholeNumber(const BuildSetting& self, const std::string& text, int minimum, int maximum,
                const char* takes) {
  const bool digits = !text.empty() && text.size() <= 9 &&
                      text.find_first_not_of("0123456789") == std::string::npos;
  const int value = digits ? std::atoi(text.c_str()) : -1;
  if (!digits || value < minimum || value > maximum) {
    refuse(self, takes, text);
  }
  return value;
}

/// A finite real number in [minimum, maximum] (read as the settings table reads numbers),
/// else refused.
double realNumber(const BuildSetting& self, const std::string& text, double minimum, double maximum,
                  const char* takes) {
  char* end = nullptr;
  errno = 0;
  const double value = text.empty() ? NAN : std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno != 0 || !std::isfinite(value) ||
      value < minimum || value > maximum) {
    refuse(self, takes, text);
  }
  return value;
}

/// The shortest text that reads back to `value`.
std::string numberText(double value) {
  std::ostringstream text;
  for (int digits = 1; digits <= 17; ++digits) {
    text.str("");
    text.precision(digits);
    text << value;
    if (std::strtod(text.str().c_str(), nullptr) == value) {
      break;
    }
  }
  return text.str();
}

std::vector<BuildSetting> makeTable() {
  std::vector<BuildSetting> rows;
  rows.push_back({"count", "--count", "N",
                  "shapes to keep (fewer if the clip runs out of distinct ones)",
                  [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
                    o.count = wholeNumber(self, text, 1, 100000, "a number of shapes from 1");
                  },
                  [](const DatabaseBuildOptions& o) { return std::to_string(o.count); }});
  rows.push_back({"duplicate_tolerance", "--duplicate-tolerance", "X",
                  "reject shapes within X * driver bbox diagonal (RMS) of a kept one",
                  [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
                    o.duplicateTolerance = realNumber(
                        self, text, 0.0, 1.0, "a share of the driver's diagonal from 0 to 1");
                  },
                  [](const DatabaseBuildOptions& o) { return numberText(o.duplicateTolerance); }});
  rows.push_back(
      {"model", "--model", "KIND",
       "pose: also fit the pose model over every candidate frame (the rest binding plus a "
       "learned correction; what `bake` evaluates by default); none: the picks only",
       [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
         if (text != "pose" && text != "none") {
           refuse(self, "pose or none", text);
         }
         o.poseModel = text == "pose";
       },
       [](const DatabaseBuildOptions& o) { return std::string(o.poseModel ? "pose" : "none"); }});
  rows.push_back(
      {"model_parts", "--model-parts", "N",
       "rigid parts of the driver the pose model reads its joints from (0 = as many as the "
       "clip shows)",
       [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
         const char* takes = "0 (found from the clip) or 2..64";
         o.model.parts = wholeNumber(self, text, 0, 64, takes);
         if (o.model.parts == 1) {
           refuse(self, takes, text);
         }
       },
       [](const DatabaseBuildOptions& o) { return std::to_string(o.model.parts); }});
  rows.push_back(
      {"model_velocity", "--model-velocity", "N",
       "frames back the pose model's velocity feature looks (0 = no velocity)",
       [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
         o.model.velocityLag = wholeNumber(self, text, 0, 60, "a number of frames 0..60");
       },
       [](const DatabaseBuildOptions& o) { return std::to_string(o.model.velocityLag); }});
  rows.push_back(
      {"model_history", "--model-history", "N",
       "frames the pose model's history feature averages (0 = no history; auto = 15 with one "
       "or two reference clips, 30 with three or more)",
       [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
         o.model.historyFrames =
             text == "auto" ? kAutoHistory
                            : wholeNumber(self, text, 0, 120, "auto or a number of frames 0..120");
       },
       [](const DatabaseBuildOptions& o) {
         return o.model.historyFrames == kAutoHistory ? std::string("auto")
                                                      : std::to_string(o.model.historyFrames);
       }});
  rows.push_back(
      {"model_siblings", "--model-siblings", "W",
       "weight of the pose model's sibling features: the relative rotation of each pair of parts "
       "with the same parent (two thighs), so the cloth between them sees both (0 = off)",
       [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
         o.model.siblingWeight = realNumber(self, text, 0.0, 100.0, "a weight from 0 to 100");
       },
       [](const DatabaseBuildOptions& o) { return numberText(o.model.siblingWeight); }});
  rows.push_back({"model_rank", "--model-rank", "N", "basis shapes the pose model keeps",
                  [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
                    o.model.rank =
                        wholeNumber(self, text, 1, 4096, "a number of basis shapes 1..4096");
                  },
                  [](const DatabaseBuildOptions& o) { return std::to_string(o.model.rank); }});
  rows.push_back(
      {"model_per_clip", "--model-per-clip", "W",
       "models of each reference clip mixed into the pose model's prediction by how close a "
       "pose is to each clip (W = the weight of the model over every clip): auto = with three "
       "or more clips, the weight of 10, 3 or 1 that best predicts each clip left out in turn, "
       "when at least 1% better than none; off = none",
       [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
         o.model.clipMixtureWeight =
             text == "auto" ? kAutoClipMixture
             : text == "off"
                 ? 0.0
                 : realNumber(self, text, 0.0, 1000.0, "auto, off or a weight from 0 to 1000");
       },
       [](const DatabaseBuildOptions& o) {
         const double w = o.model.clipMixtureWeight;
         return w == kAutoClipMixture ? std::string("auto")
                : w == 0.0            ? std::string("off")
                                      : numberText(w);
       }});
  rows.push_back(
      {"verdict_level", "--verdict-level", "P",
       "share of frames the coverage verdict's error bound is calibrated to hold for "
       "(split-conformal on the held-out reference frames; bake --coverage-tolerance flags a "
       "frame whose bound is over it)",
       [](const BuildSetting& self, DatabaseBuildOptions& o, const std::string& text) {
         const char* takes = "a share of frames from 0.5 to below 1, e.g. 0.9";
         o.model.verdictLevel = realNumber(self, text, 0.5, 1.0, takes);
         if (o.model.verdictLevel >= 1.0) {
           refuse(self, takes, text);
         }
       },
       [](const DatabaseBuildOptions& o) { return numberText(o.model.verdictLevel); }});
  return rows;
}

}  // namespace

const std::vector<BuildSetting>& buildSettingsTable() {
  static const std::vector<BuildSetting> table = makeTable();
  return table;
}

const BuildSetting& findBuildSetting(const std::string& key) {
  std::string known;
  for (const BuildSetting& row : buildSettingsTable()) {
    if (key == row.key) {
      return row;
    }
    known += (known.empty() ? "" : ", ") + std::string(row.key);
  }
  DS_THROW(kUsage, "no database build setting '", key, "' (the settings: ", known, ")");
}

void setBuildSetting(DatabaseBuildOptions& options, const std::string& key,
                     const std::string& text) {
  const BuildSetting& row = findBuildSetting(key);
  row.set(row, options, text);
}

}  // namespace drivenshape
