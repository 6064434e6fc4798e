// SPDX-License-Identifier: Apache-2.0
// Scale and correspondence checks of a shot's driver against a database (driver_check.h).

#include "driver_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <utility>

#include <drivenshape/error.h>
#include <drivenshape/mesh.h>

namespace drivenshape {
namespace {

/// "centimetres against metres" for a scale near 100, and so on; empty when no unit fits.
std::string likelyUnits(double scale) {
  struct Units {
    double factor;
    const char* driver;
    const char* database;
  };
  static const Units units[] = {
      {100.0, "centimetres", "metres"},     {1000.0, "millimetres", "metres"},
      {10.0, "millimetres", "centimetres"}, {2.54, "centimetres", "inches"},
      {39.37, "inches", "metres"},          {3.281, "feet", "metres"},
      {30.48, "centimetres", "feet"},       {12.0, "inches", "feet"}};
  for (const Units& u : units) {
    for (const bool larger : {true, false}) {
      const double factor = larger ? u.factor : 1.0 / u.factor;
      if (std::abs(std::log(scale / factor)) < std::log(1.05)) {
        std::ostringstream text;
        text << "a driver in " << (larger ? u.driver : u.database) << " against a database in "
             << (larger ? u.database : u.driver) << "?";
        return text.str();
      }
    }
  }
  return "";
}

std::string figure(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3g", value);
  return text;
}

}  // namespace

DriverMeasure measureDriver(const Database& database, const float* frame, int frameNumber) {
  const std::vector<double> ratios = edgeLengthRatios(database.driverMesh, frame);
  DriverMeasure measure;
  measure.frame = frameNumber;
  if (ratios.empty()) {
    return measure;
  }
  std::vector<double> sorted = ratios;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  measure.scale = sorted[sorted.size() / 2];
  if (!(measure.scale > 0.0)) {
    measure.spread = INFINITY;  // most edges collapsed: nothing corresponds
    return measure;
  }
  double sum = 0.0;
  for (const double ratio : ratios) {
    // A collapsed edge counts as a 1000-fold shrink, not as infinity.
    const double deviation = std::log(std::max(ratio, 1e-3 * measure.scale) / measure.scale);
    sum += deviation * deviation;
  }
  measure.spread = std::sqrt(sum / static_cast<double>(ratios.size()));
  return measure;
}

std::vector<DriverFinding> checkDriver(const Database& database, const PointCacheReader& driver,
                                       const std::vector<int>& frames,
                                       const DriverCheckLimits& limits, int samples) {
  std::vector<DriverFinding> findings;
  if (frames.empty() || samples < 1 || driver.vertexCount() != database.driverVertexCount()) {
    return findings;  // the bake's own checks name these
  }
  const int count = std::min<int>(samples, static_cast<int>(frames.size()));
  std::vector<float> xyz(static_cast<std::size_t>(driver.vertexCount()) * 3);
  std::vector<DriverMeasure> measures;
  for (int s = 0; s < count; ++s) {
    const int frame =
        frames[count == 1 ? 0 : static_cast<std::size_t>(s) * (frames.size() - 1) / (count - 1)];
    driver.readFrame(frame, xyz.data());
    measures.push_back(measureDriver(database, xyz.data(), frame));
  }
  // The worst sample by each figure: the spread decides first (a driver whose vertices do not
  // correspond also has a meaningless scale), then the scale.
  const auto spreadOf = [](const DriverMeasure& m) { return m.spread; };
  const auto scaleOf = [](const DriverMeasure& m) { return std::abs(std::log(m.scale)); };
  const auto worst = [&](auto figureOf) {
    return *std::max_element(
        measures.begin(), measures.end(),
        [&](const DriverMeasure& a, const DriverMeasure& b) { return figureOf(a) < figureOf(b); });
  };
  const DriverMeasure spread = worst(spreadOf);
  const DriverMeasure scale = worst(scaleOf);
  const auto where = [&](const DriverMeasure& m) {
    return "driver cache '" + driver.path() + "' frame " + std::to_string(m.frame) +
           " against the database's rest driver";
  };
  if (spread.spread > limits.refuseSpread) {
    findings.push_back(
        {true, where(spread) + ": its edges stretch unevenly (spread " + figure(spread.spread) +
                   "; the reference clips stay below 0.2): the vertices do not correspond to the "
                   "database's. Is this another character, or the same vertex count in another "
                   "order? Give the driver the database was built for, or force the bake if "
                   "this is intended"});
  } else if (scaleOf(scale) > std::log(limits.refuseScale)) {
    const std::string units = likelyUnits(scale.scale);
    findings.push_back(
        {true, where(scale) + ": the driver is " + figure(scale.scale) +
                   " times the database's size (median edge length)" +
                   (units.empty() ? std::string(".") : "; " + units) +
                   " Scale the driver (or rebuild the database) to the same units, or force the "
                   "bake if this is intended"});
  } else if (scaleOf(scale) > std::log(limits.warnScale) || spread.spread > limits.warnSpread) {
    findings.push_back(
        {false, "driver cache '" + driver.path() + "' against the database's rest driver: scale " +
                    figure(scale.scale) + " (frame " + std::to_string(scale.frame) +
                    "), edge spread up to " + figure(spread.spread) + " (frame " +
                    std::to_string(spread.frame) + ") over " + std::to_string(count) +
                    " frames; the reference clips have scale 1 and spreads below 0.2. The cloth "
                    "may fit badly"});
  }
  return findings;
}

std::string residualWarning(const std::vector<const FrameRecord*>& records,
                            const DriverCheckLimits& limits) {
  std::vector<std::pair<double, int>> residuals;
  for (const FrameRecord* record : records) {
    if (record->directResidual >= 0.0) {
      residuals.emplace_back(record->directResidual, record->frame);
    }
  }
  if (residuals.empty()) {
    return "";
  }
  std::sort(residuals.begin(), residuals.end());
  const double median = residuals[residuals.size() / 2].first;
  if (median <= limits.warnResidual) {
    return "";
  }
  return "the database fits the shot's driver poorly: median relative residual " + figure(median) +
         " over frames " + std::to_string(records.front()->frame) + "-" +
         std::to_string(records.back()->frame) + " (worst " + figure(residuals.back().first) +
         " at frame " + std::to_string(residuals.back().second) +
         "; the reference clips stay "
         "below 0.1). The shot may need poses the database lacks, or another database";
}

}  // namespace drivenshape
