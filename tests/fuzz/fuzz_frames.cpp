// SPDX-License-Identifier: Apache-2.0
// Frame ranges and frame patterns (src/io/frames.cpp): parseFrameRange, its round trip through
// formatFrameRange, and the pattern helpers on the same text; checkDistinctPaths on the text as
// two output names (split at its first newline), and printableText (src/core/text.h), which
// prints every bad input in messages.
//
// parseFrameRange accepts up to 10 million frames by design (frames.cpp, kMaxFrames), which takes
// seconds under ASan: texts whose numbers span more than kMaxSpan are not parsed, so the fuzzer
// explores the syntax instead of timing out on big ranges.

#include <algorithm>
#include <climits>
#include <string>
#include <vector>

#include <drivenshape/frames.h>

#include "fuzz_support.h"
#include "text.h"

namespace ds = drivenshape;

namespace {

constexpr long long kMaxSpan = 100000;

/// Largest minus smallest of the numbers written in `text` (a '-' before digits counts as a
/// sign), saturated far above kMaxSpan.
long long numberSpan(const std::string& text) {
  long long lowest = 0;
  long long highest = 0;
  bool any = false;
  for (std::size_t i = 0; i < text.size();) {
    if (text[i] < '0' || text[i] > '9') {
      ++i;
      continue;
    }
    const bool negative = i > 0 && text[i - 1] == '-';
    long long value = 0;
    for (; i < text.size() && text[i] >= '0' && text[i] <= '9'; ++i) {
      value = std::min(value * 10 + (text[i] - '0'), 1LL << 40);
    }
    value = negative ? -value : value;
    lowest = any ? std::min(lowest, value) : value;
    highest = any ? std::max(highest, value) : value;
    any = true;
  }
  return highest - lowest;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<int> frames;
  if (numberSpan(text) <= kMaxSpan &&
      ds::fuzz::expectOnlyErrors("parseFrameRange", [&] { frames = ds::parseFrameRange(text); })) {
    ds::fuzz::require(!frames.empty(), "parseFrameRange", "no frames and no error");
    std::string formatted;
    ds::fuzz::expectSuccess("formatFrameRange", [&] { formatted = ds::formatFrameRange(frames); });
    std::vector<int> again;
    ds::fuzz::expectSuccess("parseFrameRange(formatFrameRange)",
                            [&] { again = ds::parseFrameRange(formatted); });
    ds::fuzz::require(again == frames, "formatFrameRange",
                      "'" + formatted + "' does not parse back to the frames of '" + text + "'");
  }
  const bool pattern = ds::hasFramePattern(text);
  ds::fuzz::require(pattern == (ds::framePatternPosition(text) != std::string::npos),
                    "framePatternPosition", "disagrees with hasFramePattern");
  ds::fuzz::expectSuccess("sequenceStem", [&] { ds::sequenceStem(text); });
  for (const int frame : {1001, 0, -12, INT_MIN, INT_MAX}) {
    ds::fuzz::expectOnlyErrors("expandFramePattern", [&] {
      const std::string name = ds::expandFramePattern(text, frame);
      ds::fuzz::require(pattern, "expandFramePattern", "expanded a text without a frame token");
      (void)name;
    });
  }
  // Two outputs named by the text's halves (relative names: nothing is created).
  const std::size_t split = text.find('\n');
  if (split != std::string::npos && text.find('\0') == std::string::npos) {
    const std::string first = text.substr(0, split), second = text.substr(split + 1);
    const std::vector<int> few = {1, 2, 1001};
    ds::fuzz::expectOnlyErrors("checkDistinctPaths", [&] {
      ds::checkDistinctPaths({{"-o", first, ds::hasFramePattern(first)},
                              {"--report", second, ds::hasFramePattern(second)}},
                             few);
      ds::fuzz::require(first != second || first.empty(), "checkDistinctPaths",
                        "accepted two outputs with one name");
    });
  }
  std::string shown;
  ds::fuzz::expectSuccess("printableText", [&] { shown = ds::printableText(text, 64); });
  for (const char c : shown) {
    const auto byte = static_cast<unsigned char>(c);
    ds::fuzz::require(byte >= 0x20 || c == '\n' || c == '\t', "printableText",
                      "left a control byte in the text");
  }
  ds::fuzz::require(shown.size() <= 4 * 64 + 40, "printableText", "did not shorten the text");
  return 0;
}
