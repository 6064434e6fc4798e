// SPDX-License-Identifier: Apache-2.0
#include "hash.h"

#include <cstdio>

namespace drivenshape {

Hasher& Hasher::add(const void* data, std::size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) {
    mState ^= p[i];
    mState *= 0x100000001b3ULL;
  }
  return *this;
}

Hasher& Hasher::addString(const std::string& text) {
  const std::uint64_t length = text.size();
  addValue(length);
  return add(text.data(), text.size());
}

std::string hashToHex(std::uint64_t hash) {
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

bool hexToHash(const std::string& text, std::uint64_t& hash) {
  if (text.size() != 16) {
    return false;
  }
  std::uint64_t value = 0;
  for (char ch : text) {
    int digit;
    if (ch >= '0' && ch <= '9') {
      digit = ch - '0';
    } else if (ch >= 'a' && ch <= 'f') {
      digit = ch - 'a' + 10;
    } else if (ch >= 'A' && ch <= 'F') {
      digit = ch - 'A' + 10;
    } else {
      return false;
    }
    value = (value << 4) | static_cast<std::uint64_t>(digit);
  }
  hash = value;
  return true;
}

}  // namespace drivenshape
