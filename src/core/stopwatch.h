// SPDX-License-Identifier: Apache-2.0
#pragma once

// Wall-clock seconds for the timings reports carry (steady clock: never jumps with the date).

#include <chrono>

namespace drivenshape {

/// Seconds from `start` to now.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace drivenshape
