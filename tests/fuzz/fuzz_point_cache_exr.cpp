// SPDX-License-Identifier: Apache-2.0
// Point-cache EXR reader (src/io/exr_point_cache.cpp, src/io/exr_common.cpp): the header alone,
// the positions, the checks a resumed bake (--skip-existing) trusts (isCompleteExr,
// reuseProblem), and the file read as a one-frame sequence through openPointCache and
// checkPointCacheExrSequence (src/io/point_cache.cpp).

#include <vector>

#include <drivenshape/point_cache.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ds::fuzz::writeInput("cache.0001.exr", data, size);
  ds::fuzz::expectOnlyErrors("readPointCacheExrInfo", [&] { ds::readPointCacheExrInfo(path); });
  std::vector<float> xyz;
  ds::ExrPointCacheInfo info;
  const bool read = ds::fuzz::expectOnlyErrors("readPointCacheExr",
                                               [&] { info = ds::readPointCacheExr(path, xyz); });
  if (read) {
    ds::fuzz::require(info.vertexCount > 0 && xyz.size() == 3 * std::size_t(info.vertexCount),
                      "readPointCacheExr", "positions do not match dsVertexCount");
  }
  ds::fuzz::expectOnlyErrors("isCompleteExr", [&] { ds::isCompleteExr(path); });
  // With the header's own values when it has them, so the pixel checks behind them run too.
  ds::fuzz::expectOnlyErrors("reuseProblem", [&] {
    ds::reuseProblem(path, read ? info.vertexCount : 12, read ? info.topologyHash : 0,
                     read ? info.settingsHash : 0, read ? info.frame : 1001);
  });

  // `drivenshape info` on the sequence: every header against its name and the first one's.
  ds::fuzz::expectOnlyErrors("checkPointCacheExrSequence", [&] {
    ds::checkPointCacheExrSequence(ds::fuzz::scratchPath("cache.####.exr"));
  });

  std::unique_ptr<ds::PointCacheReader> sequence;
  if (!ds::fuzz::expectOnlyErrors("openPointCache(exr sequence)", [&] {
        sequence = ds::openPointCache(ds::fuzz::scratchPath("cache.####.exr"));
      })) {
    return 0;
  }
  if (read) {  // the buffer is what the reader itself allocated for this file
    std::vector<float> frame(xyz.size());
    ds::fuzz::require(sequence->vertexCount() == info.vertexCount && sequence->hasFrame(1),
                      "openPointCache(exr sequence)", "the sequence disagrees with its one file");
    ds::fuzz::expectOnlyErrors("ExrSequenceReader::readFrame",
                               [&] { sequence->readFrame(1, frame.data()); });
  }
  return 0;
}
