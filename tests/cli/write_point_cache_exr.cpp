// SPDX-License-Identifier: Apache-2.0
// Test helper for test_export_usd: writes frames of a PC2 as a point-cache EXR sequence through
// the library (writePointCacheExr), so the USD script is checked on files the tool writes.
//   write_point_cache_exr CACHE.pc2 MESH.obj FIRST LAST OUT.####.exr [FPS]
// Frame f of the output holds frame f of the cache.

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

int main(int argc, char** argv) {
  if (argc < 6) {
    std::fprintf(stderr, "usage: %s CACHE.pc2 MESH.obj FIRST LAST OUT.####.exr [FPS]\n", argv[0]);
    return 2;
  }
  try {
    const auto cache = drivenshape::openPointCache(argv[1]);
    const drivenshape::Mesh mesh = drivenshape::readObj(argv[2]);
    std::vector<float> xyz(3 * static_cast<std::size_t>(cache->vertexCount()));
    for (int frame = std::atoi(argv[3]); frame <= std::atoi(argv[4]); ++frame) {
      cache->readFrame(frame, xyz.data());
      drivenshape::ExrWriteOptions options;
      options.frame = frame;
      options.topologyHash = drivenshape::topologyHash(mesh);
      options.framesPerSecond = argc > 6 ? std::atof(argv[6]) : 24.0;
      drivenshape::writePointCacheExr(drivenshape::expandFramePattern(argv[5], frame),
                                      cache->vertexCount(), xyz.data(), nullptr, options);
    }
  } catch (const drivenshape::Error& error) {
    std::fprintf(stderr, "%s\n", error.what());
    return 1;
  }
  return 0;
}
