// SPDX-License-Identifier: Apache-2.0
#pragma once

// Does a shot's driver belong to a database? A driver in other units (centimetres against a
// database in metres) or of another character with the same vertex count bakes without any
// error and gives garbage. These checks compare the lengths of the driver mesh's edges in a
// shot frame with the database's rest driver: skinning keeps most edges' lengths (bones are
// rigid), so the median ratio is the driver's scale, and the spread of the ratios around it
// says whether the vertices correspond at all. docs/method.md gives the figures measured on
// the reference clips behind the thresholds.

#include <string>
#include <vector>

#include <drivenshape/database.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/point_cache.h>

namespace drivenshape {

/// One shot frame against the database's rest driver.
struct DriverMeasure {
  int frame = 0;
  /// Median over the driver's edges of (length in the frame / length at rest): 1 for the same
  /// character in the same units.
  double scale = 1.0;
  /// RMS over the edges of log(ratio / scale): how unevenly the edges stretch. The reference
  /// clips stay below 0.2; vertices that do not correspond (another character, another vertex
  /// order) give about 0.8.
  double spread = 0.0;
};

/// The thresholds (see docs/method.md for the measurements behind them).
struct DriverCheckLimits {
  double refuseScale = 2.0;    ///< refuse a scale outside [1/x, x]
  double warnScale = 1.05;     ///< warn outside [1/x, x]
  double refuseSpread = 0.5;   ///< refuse a spread above this
  double warnSpread = 0.3;     ///< warn above this
  double warnResidual = 0.25;  ///< warn when the direct relative residual of the fit exceeds this
};

/// Measures `frame` (3Vp floats, the database's driver topology) against the rest driver.
DriverMeasure measureDriver(const Database& database, const float* frame, int frameNumber);

/// What checkDriver found on one frame: a message naming the cache, the frame, the figures and
/// the likely cause (units, another character).
struct DriverFinding {
  bool refuse = false;  ///< beyond a refusal limit (else a warning)
  std::string message;
};

/// Measures up to `samples` of `frames` (evenly spread) of `driver`; empty when all is well.
std::vector<DriverFinding> checkDriver(const Database& database, const PointCacheReader& driver,
                                       const std::vector<int>& frames,
                                       const DriverCheckLimits& limits = {}, int samples = 5);

/// The warning for a batch of fits whose median direct relative residual
/// (FrameRecord::directResidual) exceeds limits.warnResidual, or empty.
std::string residualWarning(const std::vector<const FrameRecord*>& records,
                            const DriverCheckLimits& limits = {});

}  // namespace drivenshape
