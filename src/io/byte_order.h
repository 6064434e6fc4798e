// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace drivenshape::io {

/// PC2 and hashed integers are little-endian on disk whatever the host is. On little-endian
/// hosts the copies below compile to plain loads and stores.
inline bool hostIsLittleEndian() {
  const std::uint32_t probe = 1;
  unsigned char first;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

inline std::uint32_t loadLe32(const unsigned char* bytes) {
  return static_cast<std::uint32_t>(bytes[0]) | (static_cast<std::uint32_t>(bytes[1]) << 8) |
         (static_cast<std::uint32_t>(bytes[2]) << 16) |
         (static_cast<std::uint32_t>(bytes[3]) << 24);
}

inline void storeLe32(unsigned char* bytes, std::uint32_t value) {
  bytes[0] = static_cast<unsigned char>(value);
  bytes[1] = static_cast<unsigned char>(value >> 8);
  bytes[2] = static_cast<unsigned char>(value >> 16);
  bytes[3] = static_cast<unsigned char>(value >> 24);
}

inline std::int32_t loadLeInt32(const unsigned char* bytes) {
  const std::uint32_t bits = loadLe32(bytes);
  std::int32_t value;
  std::memcpy(&value, &bits, 4);
  return value;
}

inline float loadLeFloat(const unsigned char* bytes) {
  const std::uint32_t bits = loadLe32(bytes);
  float value;
  std::memcpy(&value, &bits, 4);
  return value;
}

inline void storeLeInt32(unsigned char* bytes, std::int32_t value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, 4);
  storeLe32(bytes, bits);
}

inline void storeLeFloat(unsigned char* bytes, float value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, 4);
  storeLe32(bytes, bits);
}

/// Swaps every 4-byte word of `words` in place (little-endian file <-> big-endian host).
inline void swapWords(void* words, std::size_t count) {
  auto* bytes = static_cast<unsigned char*>(words);
  for (std::size_t i = 0; i < count; ++i, bytes += 4) {
    const unsigned char b0 = bytes[0];
    const unsigned char b1 = bytes[1];
    bytes[0] = bytes[3];
    bytes[1] = bytes[2];
    bytes[2] = b1;
    bytes[3] = b0;
  }
}

}  // namespace drivenshape::io
