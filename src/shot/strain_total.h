// SPDX-License-Identifier: Apache-2.0
#pragma once

// A shot's strain figures (ClothMetrics::strain) gathered frame by frame, with the nearest-rank
// 95th percentile exact over every value yet without keeping them all.

#include <vector>

#include <drivenshape/evaluate.h>

namespace drivenshape {

/// The StrainFigures of `total` values given in any number of add() calls. The nearest-rank
/// percentile is the m-th largest value, m = total - ceil(0.95 total) + 1, so only the largest
/// m values seen so far are kept (about 5% of them, at most 2m at a time): memory of 8 bytes
/// per edge per 10 frames, instead of every edge of every frame.
class StrainTotal {
 public:
  explicit StrainTotal(long long total);
  /// Adds the strains of one frame (signed, as edgeStrains gives them).
  void add(const std::vector<double>& strains);
  /// The figures; Error(kInternal) unless exactly `total` values were added.
  StrainFigures figures();

 private:
  void keepLargest();

  long long mTotal = 0;
  long long mCount = 0;
  long long mOver = 0;
  double mSum = 0.0;
  std::size_t mKeep = 0;         // m
  std::vector<double> mLargest;  // a superset of the m largest magnitudes added so far
};

/// The figures of one set of strains (a frame's edges): a StrainTotal of exactly them.
StrainFigures strainFigures(const std::vector<double>& strains);

}  // namespace drivenshape
