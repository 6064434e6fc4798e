// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <system_error>
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

/// The regular files of the sequence `pattern` (one token, in the file name) that exist, by
/// frame. A file belongs to the sequence when its name is the pattern with the token replaced
/// by a frame number written exactly as formatFrameNumber writes it: `####` takes `1001`,
/// `0012`, `-0012` and `12345`, but not `012` or `01001`, so each frame has one name. Empty
/// for a pattern without exactly one token in its file name; `ec` is set when the folder
/// cannot be listed.
std::map<int, std::string> listSequenceFiles(const std::string& pattern, std::error_code& ec);

}  // namespace drivenshape::io
