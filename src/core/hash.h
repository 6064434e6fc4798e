// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace drivenshape {

/// 64-bit FNV-1a, incrementally. Used for topology hashes, settings hashes and the
/// checksums of database blocks: stable across platforms and versions.
class Hasher {
 public:
  Hasher() = default;
  /// Continues a stream whose value so far is `value` (FNV-1a's state is its value).
  explicit Hasher(std::uint64_t value) : mState(value) {}
  Hasher& add(const void* data, std::size_t bytes);
  template <typename T>
  Hasher& addValue(const T& value) {
    return add(&value, sizeof(T));
  }
  Hasher& addString(const std::string& text);
  std::uint64_t value() const { return mState; }

 private:
  std::uint64_t mState = 0xcbf29ce484222325ULL;
};

/// 16 lowercase hex digits.
std::string hashToHex(std::uint64_t hash);
/// Parses 16 hex digits; returns false on anything else.
bool hexToHash(const std::string& text, std::uint64_t& hash);

}  // namespace drivenshape
