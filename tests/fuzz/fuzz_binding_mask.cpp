// SPDX-License-Identifier: Apache-2.0
// Binding-mask JSON (src/database/binding_mask.cpp) against the fixed driver and driven
// meshes of fuzz_support.h; a mask that parses must match the BindingMask contract.

#include <algorithm>

#include <drivenshape/binding.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const ds::Mesh& driver = ds::fuzz::fixedDriver();
  const ds::Mesh& driven = ds::fuzz::fixedDriven();
  ds::fuzz::expectOnlyErrors("parseBindingMask", [&] {
    const ds::BindingMask mask = ds::parseBindingMask(text, "fuzz.json", driver, driven);
    ds::fuzz::require(mask.drivenVertexCount() == driven.vertexCount(), "parseBindingMask",
                      "the mask does not cover the driven mesh");
    for (const int c : mask.vertexClasses()) {
      ds::fuzz::require(c >= -1 && c < mask.classCount(), "parseBindingMask",
                        "vertex class out of range");
    }
    for (int c = 0; c < mask.classCount(); ++c) {
      const std::vector<int>& triangles = mask.classTriangles(c);
      ds::fuzz::require(!triangles.empty() && std::is_sorted(triangles.begin(), triangles.end()) &&
                            triangles.front() >= 0 && triangles.back() < driver.triangleCount(),
                        "parseBindingMask", "a class is empty, unsorted or out of range");
    }
  });
  return 0;
}
