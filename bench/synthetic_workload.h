// SPDX-License-Identifier: Apache-2.0
// The synthetic character of the benchmarks (drivenshape_bench, drivenshape_bench_exr): a
// bending tube (driver) inside a looser tube (driven), 1 unit (a metre) long, and the
// workloads W1 and W2 of docs/performance.md built from it. Generated deterministically.

#pragma once

#include <cmath>
#include <string>

#include <drivenshape/error.h>
#include <drivenshape/mesh.h>

namespace drivenshape::bench {

/// A tube of `rings` x `segments` quads around the z axis, radius r, length 1.
inline Mesh tube(int rings, int segments, float radius) {
  Mesh mesh;
  mesh.positions.resize(rings * segments, 3);
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const float angle = 2.0f * float(M_PI) * j / segments;
      mesh.positions.row(i * segments + j) << radius * std::cos(angle), radius * std::sin(angle),
          float(i) / (rings - 1);
    }
  }
  mesh.faceStart.push_back(0);
  for (int i = 0; i + 1 < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const int j1 = (j + 1) % segments;
      for (int v :
           {i * segments + j, i * segments + j1, (i + 1) * segments + j1, (i + 1) * segments + j}) {
        mesh.faceVertices.push_back(v);
      }
      mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
      mesh.faceGroup.push_back(0);
    }
  }
  mesh.groupNames = {"tube"};
  mesh.triangulate();
  return mesh;
}

/// Bends the tube by angles (a, b) about x and y, growing along z, plus a twist c.
inline void bend(const Mesh& rest, float a, float b, float c, float* out) {
  for (int v = 0; v < rest.vertexCount(); ++v) {
    const float x = rest.positions(v, 0), y = rest.positions(v, 1), z = rest.positions(v, 2);
    const float ax = a * z, by = b * z, tw = c * z;
    const float x1 = x * std::cos(tw) - y * std::sin(tw);
    const float y1 = x * std::sin(tw) + y * std::cos(tw);
    const float y2 = y1 * std::cos(ax) - z * std::sin(ax);
    const float z2 = y1 * std::sin(ax) + z * std::cos(ax);
    out[3 * v] = x1 * std::cos(by) + z2 * std::sin(by);
    out[3 * v + 1] = y2;
    out[3 * v + 2] = -x1 * std::sin(by) + z2 * std::cos(by);
  }
}

struct Workload {
  std::string name;
  int driverRings, driverSegments, drivenRings, drivenSegments, shapes, frames;
};

inline Workload workload(const std::string& name) {
  if (name == "W1") {
    return {"W1", 100, 50, 100, 50, 30, 1000};  // 5,000 / 5,000 vertices
  }
  if (name == "W2") {
    return {"W2", 500, 100, 1000, 200, 64, 240};  // 50,000 / 200,000 vertices
  }
  DS_THROW(kUsage, "--workload takes W1 or W2 (got '", name, "')");
}

}  // namespace drivenshape::bench
