// SPDX-License-Identifier: Apache-2.0
#pragma once

// The one loop behind every check that names the frame and vertex of a NaN or infinite
// position (caches read by the bake and eval, the evaluator's input and output, the
// closest-point backends' input).

#include <cmath>
#include <cstddef>
#include <string>

#include <drivenshape/error.h>

namespace drivenshape {

/// Index of the first NaN or infinite value of data[0, count), or `count` when there is none.
inline std::size_t firstNonFinite(const float* data, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) {
    if (!std::isfinite(data[i])) {
      return i;
    }
  }
  return count;
}

/// Throws Error(kInput) "<source> frame F vertex V is not a finite number; ..." when the
/// `values` floats at `xyz` (a frame, 3 per vertex) hold a NaN or an infinity.
inline void requireFiniteFrame(const std::string& source, int frame, const float* xyz,
                               std::size_t values) {
  const std::size_t bad = firstNonFinite(xyz, values);
  if (bad < values) {
    DS_THROW(kInput, source, " frame ", frame, " vertex ", bad / 3,
             " is not a finite number; fix the cache or leave the frame out");
  }
}

}  // namespace drivenshape
