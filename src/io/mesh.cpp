#include <drivenshape/mesh.h>

#include <algorithm>
#include <cstdint>

#include <drivenshape/hash.h>

#include "byte_order.h"

namespace drivenshape {
namespace {

/// Hashes ints as little-endian bytes so the hash is the same on every host.
void addInts(Hasher& hasher, const int* values, std::size_t count) {
  if (io::hostIsLittleEndian()) {
    hasher.add(values, count * sizeof(int));
    return;
  }
  for (std::size_t i = 0; i < count; ++i) {
    unsigned char bytes[4];
    io::storeLeInt32(bytes, values[i]);
    hasher.add(bytes, 4);
  }
}

void addInt(Hasher& hasher, int value) {
  addInts(hasher, &value, 1);
}

}  // namespace

static_assert(sizeof(int) == 4, "topology hashes assume 32-bit int");

void Mesh::triangulate() {
  // Counted from faceStart, not faceGroup, so meshes built in code without groups work too.
  const int faces = faceStart.empty() ? 0 : static_cast<int>(faceStart.size()) - 1;
  int count = 0;
  for (int f = 0; f < faces; ++f) {
    count += std::max(0, faceStart[f + 1] - faceStart[f] - 2);
  }
  triangles.resize(count, 3);
  triangleFace.resize(static_cast<std::size_t>(count));
  int t = 0;
  for (int f = 0; f < faces; ++f) {
    const int begin = faceStart[f];
    const int end = faceStart[f + 1];
    for (int i = begin + 1; i + 1 < end; ++i, ++t) {
      triangles(t, 0) = faceVertices[begin];
      triangles(t, 1) = faceVertices[i];
      triangles(t, 2) = faceVertices[i + 1];
      triangleFace[t] = f;
    }
  }
}

std::uint64_t topologyHash(const Mesh& mesh) {
  Hasher hasher;
  hasher.addString("drivenshape.topology.mesh");
  addInt(hasher, mesh.vertexCount());
  // A mesh without faces may carry faceStart {} or {0}; both are the same topology.
  const int zero = 0;
  const bool noStart = mesh.faceStart.empty();
  addInt(hasher, noStart ? 1 : static_cast<int>(mesh.faceStart.size()));
  addInts(hasher, noStart ? &zero : mesh.faceStart.data(), noStart ? 1 : mesh.faceStart.size());
  addInt(hasher, static_cast<int>(mesh.faceVertices.size()));
  addInts(hasher, mesh.faceVertices.data(), mesh.faceVertices.size());
  return hasher.value();
}

std::uint64_t topologyHash(int vertexCount) {
  Hasher hasher;
  hasher.addString("drivenshape.topology.points");
  addInt(hasher, vertexCount);
  return hasher.value();
}

Bounds computeBounds(const float* xyz, int vertexCount) {
  Bounds bounds;
  if (vertexCount <= 0) {
    return bounds;
  }
  Eigen::Vector3f lo(xyz[0], xyz[1], xyz[2]);
  Eigen::Vector3f hi = lo;
  for (int v = 1; v < vertexCount; ++v) {
    const float* p = xyz + 3 * static_cast<std::size_t>(v);
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[k]);
      hi[k] = std::max(hi[k], p[k]);
    }
  }
  bounds.min = lo;
  bounds.max = hi;
  return bounds;
}

}  // namespace drivenshape
