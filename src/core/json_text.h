// SPDX-License-Identifier: Apache-2.0
// JSON in and out for the readers and writers of the library and its apps (nlohmann::json is
// private to drivenshape: no public header includes it). Every parse and every dump goes
// through here so that no file content and no path, whatever its bytes, can escape as a JSON
// library exception.

#pragma once

#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include <drivenshape/error.h>

namespace drivenshape {

/// Parses `text` as JSON. Any JSON error (syntax, bytes that are not UTF-8, a number beyond
/// double such as 1e999) becomes Error(kInput) "<source>: not valid JSON (...)".
inline nlohmann::json parseJsonText(std::string_view text, const std::string& source) {
  try {
    return nlohmann::json::parse(text.begin(), text.end());
  } catch (const nlohmann::json::exception& error) {
    DS_THROW(kInput, source, ": not valid JSON (", error.what(), ")");
  }
}

/// Serialises `value` (`indent` < 0: one line). Strings that are not valid UTF-8 (paths and
/// names taken from the file system or from foreign files) have each bad byte written as
/// U+FFFD instead of making the dump throw.
inline std::string jsonText(const nlohmann::json& value, int indent = -1) {
  return value.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

/// `value` as an int in [min, max]; anything else (a fraction, a string, a number out of
/// range) is Error(kInput) naming `where`. nlohmann's get<int>() would convert silently.
inline int jsonInt(const nlohmann::json& value, const std::string& where,
                   long long min = std::numeric_limits<int>::min(),
                   long long max = std::numeric_limits<int>::max()) {
  if (value.is_number_unsigned()) {
    const auto number = value.get<unsigned long long>();
    if (max >= 0 && number <= static_cast<unsigned long long>(max) &&
        static_cast<long long>(number) >= min) {
      return static_cast<int>(number);
    }
  } else if (value.is_number_integer()) {
    const auto number = value.get<long long>();
    if (number >= min && number <= max) {
      return static_cast<int>(number);
    }
  }
  DS_THROW(kInput, where, " is ", jsonText(value), "; expected a whole number from ", min, " to ",
           max);
}

}  // namespace drivenshape
