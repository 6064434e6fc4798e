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
