#pragma once

#include <string>
#include <vector>

namespace drivenshape {

/// Parses a frame range: `1001`, `1001-1100`, `1001-1100x2` (step), and comma lists of those
/// (`1001,1005,1010-1020`). Frames keep the order given, duplicates removed (first kept).
/// Negative frames are allowed (`-10--1`). Throws Error(kUsage) naming the text when it is
/// malformed, when a step is not positive, when start > end, or when no frame results.
std::vector<int> parseFrameRange(const std::string& text);

/// Formats frames back compactly (`1001-1100`, `1-9x2,20`), for messages and reports.
std::string formatFrameRange(const std::vector<int>& frames);

/// True when `pattern` holds a frame token: a run of `#` (one digit each), `%0Nd`/`%d`, or
/// `$F`/`$FN` (Houdini, N digits).
bool hasFramePattern(const std::string& pattern);

/// Where the (first) frame token of `pattern` starts, or std::string::npos if it has none.
std::size_t framePatternPosition(const std::string& pattern);

/// The name of a sequence: the file-name part before the frame token, without trailing '.',
/// '_' or '-' (out/cloth.####.exr -> "cloth"); "bake" when nothing is left. Reports and farm
/// logs are named after it.
std::string sequenceStem(const std::string& pattern);

/// Replaces the frame token with `frame`, zero padded to the token's width (negative frames
/// keep the sign before the padding: -0012). Throws Error(kUsage) if there is no token or more
/// than one.
std::string expandFramePattern(const std::string& pattern, int frame);

}  // namespace drivenshape
