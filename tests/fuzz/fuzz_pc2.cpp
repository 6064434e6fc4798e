// SPDX-License-Identifier: Apache-2.0
// PC2 reader (src/io/pc2.cpp): openPc2 (header checks, size against the header, the frames the
// samples fall on), then every frame it claims, read one by one and as a block (readFrames):
// each read succeeds or refuses a non-finite position.

#include <algorithm>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/point_cache.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

namespace {

/// Floats read per input at most: the file holds every frame it claims (its size is checked
/// against the header), so this only bounds the time one input takes.
constexpr std::size_t kFloatBudget = 1 << 20;

/// Runs `read`: it succeeds, or throws drivenshape::Error for a position that is not finite.
template <typename Read>
void readFiniteOrRefused(const char* what, Read&& read) {
  try {
    read();
  } catch (const ds::Error& error) {
    ds::fuzz::require(std::string(error.what()).find("is not a finite number") != std::string::npos,
                      what, std::string("refused a frame the file holds: ") + error.what());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ds::fuzz::writeInput("input.pc2", data, size);
  std::unique_ptr<ds::PointCacheReader> cache;
  if (!ds::fuzz::expectOnlyErrors("openPc2", [&] { cache = ds::openPc2(path); })) {
    return 0;
  }
  const int vertices = cache->vertexCount();
  const std::vector<int> frames = cache->frames();
  ds::fuzz::require(vertices > 0, "openPc2", "a cache without vertices was opened");
  ds::fuzz::require(std::is_sorted(frames.begin(), frames.end()) &&
                        std::adjacent_find(frames.begin(), frames.end()) == frames.end(),
                    "openPc2", "frames() is not ascending and unique");
  const std::size_t frameFloats = 3 * static_cast<std::size_t>(vertices);
  ds::fuzz::require(frames.empty() || frames.size() <= size / (frameFloats * 4), "openPc2",
                    "the cache claims more frames than the file holds");
  // Sized only when there are frames: then the file holds one, so this is bounded by its size.
  std::vector<float> xyz(frames.empty() ? 0 : frameFloats);
  std::size_t budget = kFloatBudget;
  for (const int frame : frames) {
    if (budget < frameFloats) {
      break;
    }
    budget -= frameFloats;
    ds::fuzz::require(cache->hasFrame(frame), "Pc2Reader::hasFrame", "a listed frame is missing");
    // Every listed frame is in the file (its size was checked): reading it must succeed, unless
    // it holds a NaN or infinite position, which is refused naming the frame and vertex.
    readFiniteOrRefused("Pc2Reader::readFrame", [&] { cache->readFrame(frame, xyz.data()); });
  }
  for (const int frame : {frames.empty() ? 0 : frames.front() - 1, -2147483647 - 1, 2147483647}) {
    if (!cache->hasFrame(frame)) {
      ds::fuzz::expectOnlyErrors("Pc2Reader::readFrame(missing)",
                                 [&] { cache->readFrame(frame, xyz.data()); });
    }
  }
  if (!frames.empty() && frameFloats * std::min<std::size_t>(frames.size(), 4) <= kFloatBudget) {
    const std::vector<int> some(frames.begin(),
                                frames.begin() + std::min<std::ptrdiff_t>(frames.size(), 4));
    readFiniteOrRefused("readFrames(pc2)", [&] { ds::readFrames(*cache, some); });
  }
  return 0;
}
