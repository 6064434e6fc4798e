// SPDX-License-Identifier: Apache-2.0
#pragma once
// Synthetic meshes and data for the layer tests (no files from /work/shared).

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <drivenshape/mesh.h>

namespace drivenshape::testing {

/// A flat grid of (columns x rows) vertices in the plane z = height, spacing `step`, offset to
/// `origin` (far from 0, like a garment in a scene); quads, vertex v = row * columns + column.
/// Faces whose left column is below `splitColumn` are in group "left", the others in "right".
inline Mesh gridMesh(int columns, int rows, int splitColumn, float step = 0.05f,
                     float originX = 100.0f, float originY = 50.0f, float height = 0.3f) {
  Mesh mesh;
  mesh.positions.resize(columns * rows, 3);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      mesh.positions.row(r * columns + c) << originX + step * static_cast<float>(c),
          originY + step * static_cast<float>(r), height;
    }
  }
  mesh.groupNames = {"left", "right"};
  mesh.faceStart.push_back(0);
  for (int r = 0; r + 1 < rows; ++r) {
    for (int c = 0; c + 1 < columns; ++c) {
      const int v = r * columns + c;
      for (int corner : {v, v + 1, v + 1 + columns, v + columns}) {
        mesh.faceVertices.push_back(corner);
      }
      mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
      mesh.faceGroup.push_back(c < splitColumn ? 0 : 1);
    }
  }
  mesh.triangulate();
  return mesh;
}

/// F frames of the mesh's positions moved by a smooth per-frame offset plus noise of `spread`.
inline std::vector<float> jitteredFrames(const Mesh& mesh, int frameCount, float spread,
                                         std::uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> jitter(-spread, spread);
  std::vector<float> frames;
  frames.reserve(static_cast<std::size_t>(frameCount) * 3 * mesh.vertexCount());
  for (int f = 0; f < frameCount; ++f) {
    for (int v = 0; v < mesh.vertexCount(); ++v) {
      for (int a = 0; a < 3; ++a) {
        frames.push_back(mesh.positions(v, a) + 0.01f * static_cast<float>(f) + jitter(random));
      }
    }
  }
  return frames;
}

inline bool sameBits(float a, float b) {
  return std::memcmp(&a, &b, sizeof(float)) == 0;
}

}  // namespace drivenshape::testing
