#pragma once

// The one loop behind every check that names the frame and vertex of a NaN or infinite
// position (caches read by the bake and eval, the evaluator's input and output, the
// closest-point backends' input).

#include <cmath>
#include <cstddef>

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

}  // namespace drivenshape
