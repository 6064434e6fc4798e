// SPDX-License-Identifier: Apache-2.0
// Rig JSON for the pose model's parts (src/database/rig.cpp) against the fixed driver of
// fuzz_support.h: a rig that parses gives every driver vertex a part and every part a parent
// that is another part or none, without cycles.

#include <set>
#include <vector>

#include <drivenshape/pose_model.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const int vertices = ds::fuzz::fixedDriver().vertexCount();
  ds::fuzz::expectOnlyErrors("parseRigParts", [&] {
    std::vector<int> partOf, parentOf;
    ds::parseRigParts(text, "fuzz.json", vertices, partOf, parentOf);
    const int parts = static_cast<int>(parentOf.size());
    ds::fuzz::require(partOf.size() == static_cast<std::size_t>(vertices), "parseRigParts",
                      "not one part per driver vertex");
    for (int p : partOf) {
      ds::fuzz::require(p >= 0 && p < parts, "parseRigParts", "a vertex names no part");
    }
    for (int p = 0; p < parts; ++p) {
      std::set<int> seen;
      for (int q = p; q >= 0; q = parentOf[static_cast<std::size_t>(q)]) {
        ds::fuzz::require(q < parts && seen.insert(q).second, "parseRigParts",
                          "a parent is out of range or the parents loop");
      }
    }
  });
  return 0;
}
