// SPDX-License-Identifier: Apache-2.0
#pragma once

// Small text helpers shared by the readers (private to the project).

#include <string>

namespace drivenshape {

/// `text` without leading and trailing spaces and tabs.
inline std::string trimSpaces(const std::string& text) {
  const std::size_t first = text.find_first_not_of(" \t");
  if (first == std::string::npos) {
    return {};
  }
  const std::size_t last = text.find_last_not_of(" \t");
  return text.substr(first, last - first + 1);
}

}  // namespace drivenshape

namespace drivenshape {

/// `text` made safe to print in a message: control characters and bytes that are not valid
/// UTF-8 are written as `\xNN` (valid UTF-8, such as an accented file name, stays as it is), and
/// a text longer than `maxBytes` keeps its start and end around "...(N bytes)...".
std::string printableText(const std::string& text, std::size_t maxBytes = 4000);

/// Whether `text` is well-formed UTF-8 (no overlong forms, surrogates or code points past
/// U+10FFFF).
bool isUtf8(const std::string& text);

}  // namespace drivenshape
