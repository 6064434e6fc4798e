// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace drivenshape::io {

/// One frame token inside a file name pattern.
///
///   "cloth.####.exr"   -> pos 6, length 4, width 4
///   "cloth.%04d.exr"   -> pos 6, length 4, width 4      ("%d": width 0)
///   "cloth.$F4.exr"    -> pos 6, length 3, width 4      ("$F": width 0, no padding)
///
/// `width` is the minimum number of digits (zero padded); 0 and 1 mean no padding.
struct FrameToken {
  std::size_t pos = 0;
  std::size_t length = 0;
  int width = 0;
};

/// All frame tokens of `pattern`, left to right.
std::vector<FrameToken> findFrameTokens(const std::string& pattern);

/// `frame` as the token writes it: the sign first, then at least `width` digits.
std::string formatFrameNumber(int frame, int width);

}  // namespace drivenshape::io
