// SPDX-License-Identifier: Apache-2.0
// Weight maps (src/io/weight_map.cpp) for the fixed driven mesh of fuzz_support.h: an input
// that starts with the EXR magic number is read as NAME.exr, one that starts with "group:" is the
// spec itself, anything else is NAME.json. A map that reads must hold one value in [0, 1] per
// vertex, and so must the map softened across a few edge rings.

#include <cstring>
#include <vector>

#include <drivenshape/layers.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const unsigned char kExrMagic[4] = {0x76, 0x2f, 0x31, 0x01};
  const ds::Mesh& driven = ds::fuzz::fixedDriven();
  std::string spec;
  if (size >= 6 && std::memcmp(data, "group:", 6) == 0) {
    spec.assign(reinterpret_cast<const char*>(data), size);
  } else if (size >= 4 && std::memcmp(data, kExrMagic, 4) == 0) {
    spec = ds::fuzz::writeInput("weights.exr", data, size);
  } else {
    spec = ds::fuzz::writeInput("weights.json", data, size);
  }
  std::vector<float> weights;
  if (!ds::fuzz::expectOnlyErrors("readWeightMap",
                                  [&] { weights = ds::readWeightMap(spec, driven, "fuzz"); })) {
    return 0;
  }
  ds::fuzz::require(weights.size() == static_cast<std::size_t>(driven.vertexCount()),
                    "readWeightMap", "the map does not have one value per vertex");
  for (const float w : weights) {
    ds::fuzz::require(w >= 0.0f && w <= 1.0f, "readWeightMap", "a weight is outside [0, 1]");
  }
  const int rings = static_cast<int>(data[size - 1] % 4);  // size > 0: empty maps do not read
  std::vector<float> smooth;
  ds::fuzz::expectSuccess("smoothWeightMap",
                          [&] { smooth = ds::smoothWeightMap(weights, driven, rings); });
  for (const float w : smooth) {
    ds::fuzz::require(w >= 0.0f && w <= 1.0f, "smoothWeightMap", "a weight is outside [0, 1]");
  }
  return 0;
}
