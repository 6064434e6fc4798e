// SPDX-License-Identifier: Apache-2.0
// Position-map EXR reader (src/io/posmap_exr.cpp): the header reader behind
// `drivenshape info` (with the channel naming it tells from the channels: R G B or the legacy
// P.X P.Y P.Z), the kind test, and the completeness check.

#include <drivenshape/point_cache.h>
#include <drivenshape/position_map.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ds::fuzz::writeInput("map.0001.exr", data, size);
  ds::PositionMapInfo info;
  const bool read = ds::fuzz::expectOnlyErrors("readPositionMapExrInfo",
                                               [&] { info = ds::readPositionMapExrInfo(path); });
  bool isMap = false;
  ds::fuzz::expectOnlyErrors("isPositionMapExr", [&] { isMap = ds::isPositionMapExr(path); });
  ds::fuzz::require(!read || isMap, "isPositionMapExr",
                    "false for a file readPositionMapExrInfo reads");
  if (read) {
    ds::fuzz::require(info.width > 0 && info.height > 0, "readPositionMapExrInfo",
                      "a map without pixels was read");
    ds::fuzz::require(info.channels == ds::PositionMapChannels::kRgba ||
                          info.channels == ds::PositionMapChannels::kLegacy,
                      "readPositionMapExrInfo", "a channel naming outside the enum");
  }
  ds::fuzz::expectOnlyErrors("isCompleteExr", [&] { ds::isCompleteExr(path); });
  return 0;
}
