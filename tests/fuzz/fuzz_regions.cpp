// SPDX-License-Identifier: Apache-2.0
// Region JSON (src/database/regions.cpp) against the fixed driver and driven meshes of
// fuzz_support.h; the mixing weights of a region set that parses must be a partition of unity.

#include <cmath>
#include <vector>

#include <drivenshape/regions.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

namespace {

void checkPartition(const std::vector<float>& mix, int regions, int vertices, const char* what) {
  ds::fuzz::require(mix.size() == static_cast<std::size_t>(regions) * vertices, what,
                    "mixing weights are not R x V");
  for (int v = 0; v < vertices; ++v) {
    double sum = 0.0;
    for (int r = 0; r < regions; ++r) {
      const float w = mix[static_cast<std::size_t>(r) * vertices + v];
      ds::fuzz::require(w >= 0.0f && w <= 1.0f, what, "a mixing weight is outside [0, 1]");
      sum += w;
    }
    ds::fuzz::require(std::abs(sum - 1.0) < 1e-4, what, "mixing weights do not sum to 1");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const ds::Mesh& driver = ds::fuzz::fixedDriver();
  const ds::Mesh& driven = ds::fuzz::fixedDriven();
  ds::fuzz::expectOnlyErrors("parseRegions", [&] {
    const ds::RegionSet set = ds::parseRegions(text, "fuzz.json", driver, driven);
    ds::fuzz::require(set.count() >= 1, "parseRegions", "no regions");
    checkPartition(set.driverMix, set.count(), driver.vertexCount(), "parseRegions(driverMix)");
    checkPartition(set.drivenMix, set.count(), driven.vertexCount(), "parseRegions(drivenMix)");
  });
  return 0;
}
