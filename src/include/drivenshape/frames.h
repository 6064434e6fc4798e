// SPDX-License-Identifier: Apache-2.0
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
/// keep the sign before the padding: -0012). Throws Error(kUsage) if there is no token, more
/// than one, or the token is in a folder name (out/####/c.exr: a folder per frame).
std::string expandFramePattern(const std::string& pattern, int frame);

/// One file or file sequence a command reads or writes, by the option that names it.
struct NamedPath {
  std::string option;  ///< how the user named it: "-o", "--report", "--driver" ...
  std::string path;    ///< a path, or a pattern when `sequence`
  bool sequence = false;
};

/// Refuses, before any work, a command whose outputs could name the same file, or whose output
/// would replace one of its inputs: Error(kUsage) naming both options and the file. Sequences
/// are expanded over `frames`; paths are compared after resolving the folders that exist (so
/// `a/../b.exr`, `./b.exr` and a link to the folder are the same file).
void checkDistinctPaths(const std::vector<NamedPath>& outputs, const std::vector<int>& frames,
                        const std::vector<NamedPath>& inputs = {});

}  // namespace drivenshape
