// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/mesh.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <drivenshape/error.h>

#include "hash.h"

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

void validateMesh(const Mesh& mesh, const std::string& source) {
  constexpr std::size_t kMaxInt = static_cast<std::size_t>(std::numeric_limits<int>::max());
  const std::size_t corners = mesh.faceVertices.size();
  if (corners > kMaxInt || mesh.faceStart.size() > kMaxInt) {
    DS_THROW(kInput, source, ": ", corners, " face corners; at most ", kMaxInt, " are supported");
  }
  const std::size_t faces = mesh.faceStart.empty() ? 0 : mesh.faceStart.size() - 1;
  if (mesh.faceStart.empty() ? corners != 0
                             : mesh.faceStart.front() != 0 ||
                                   static_cast<std::size_t>(mesh.faceStart.back()) != corners) {
    DS_THROW(kInput, source, ": the face offsets do not span the ", corners,
             " face corners; the mesh data is corrupt");
  }
  if (mesh.faceGroup.size() != faces) {
    DS_THROW(kInput, source, ": ", mesh.faceGroup.size(), " face group ids for ", faces,
             " faces; the mesh data is corrupt");
  }
  if (!mesh.faceUvs.empty() && mesh.faceUvs.size() != corners) {
    DS_THROW(kInput, source, ": ", mesh.faceUvs.size(), " texture-coordinate ids for ", corners,
             " face corners; the mesh data is corrupt");
  }
  const long long vertices = mesh.vertexCount();
  const long long uvs = static_cast<long long>(mesh.uvs.size());
  const long long groups = static_cast<long long>(mesh.groupNames.size());
  long long triangles = 0;
  for (std::size_t f = 0; f < faces; ++f) {
    const int begin = mesh.faceStart[f];
    const int end = mesh.faceStart[f + 1];
    if (end < begin + 3) {
      DS_THROW(kInput, source, ": face ", f, " has ", end < begin ? -1LL : end - begin,
               " corners (offsets ", begin, "..", end, "); a face needs at least 3");
    }
    if (static_cast<std::size_t>(end) > corners) {
      DS_THROW(kInput, source, ": face ", f, " ends at corner ", end, " of ", corners,
               "; the mesh data is corrupt");
    }
    triangles += end - begin - 2;
    if (mesh.faceGroup[f] < 0 || mesh.faceGroup[f] >= groups) {
      DS_THROW(kInput, source, ": face ", f, " is in group ", mesh.faceGroup[f], " of ", groups,
               "; the mesh data is corrupt");
    }
    for (int c = begin; c < end; ++c) {
      const int v = mesh.faceVertices[static_cast<std::size_t>(c)];
      if (v < 0 || v >= vertices) {
        DS_THROW(kInput, source, ": face ", f, " uses vertex ", v, " of ", vertices, " (ids 0-",
                 vertices - 1, ")");
      }
      const int t = mesh.faceUvs.empty() ? -1 : mesh.faceUvs[static_cast<std::size_t>(c)];
      if (t < -1 || t >= uvs) {
        DS_THROW(kInput, source, ": face ", f, " uses texture coordinate ", t, " of ", uvs);
      }
    }
  }
  if (triangles > std::numeric_limits<int>::max()) {
    DS_THROW(kInput, source, ": ", triangles, " triangles; at most ",
             std::numeric_limits<int>::max(), " are supported");
  }
}

void Mesh::triangulate() {
  // Counted from faceStart, not faceGroup, so meshes built in code without groups work too.
  const int faces = faceStart.empty() ? 0 : static_cast<int>(faceStart.size()) - 1;
  // validateMesh() bounds the count by INT_MAX for anything a reader returns; a mesh built in
  // code that exceeds it is a caller bug, caught here before the int overflows.
  long long count = 0;
  for (int f = 0; f < faces; ++f) {
    count += std::max(0LL, static_cast<long long>(faceStart[f + 1]) - faceStart[f] - 2);
  }
  if (count > std::numeric_limits<int>::max()) {
    DS_THROW(kInternal, "Mesh::triangulate: ", count, " triangles do not fit in an int");
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

double boundsDiagonal(const Mesh& mesh) {
  return computeBounds(mesh.positions.data(), mesh.vertexCount()).diagonal();
}

namespace {

/// Every polygon's sides (each corner with the next, the last with the first) as (a, b) with
/// a < b, once per face that has it, sorted; a side naming one vertex twice is none.
std::vector<MeshEdge> polygonSides(const Mesh& mesh) {
  std::vector<MeshEdge> sides;
  sides.reserve(mesh.faceVertices.size());
  for (std::size_t f = 0; f + 1 < mesh.faceStart.size(); ++f) {
    const auto begin = static_cast<std::size_t>(mesh.faceStart[f]);
    const auto end = static_cast<std::size_t>(mesh.faceStart[f + 1]);
    for (std::size_t c = begin; c < end; ++c) {
      const int a = mesh.faceVertices[c];
      const int b = mesh.faceVertices[c + 1 < end ? c + 1 : begin];
      if (a != b) {
        sides.push_back({std::min(a, b), std::max(a, b)});
      }
    }
  }
  std::sort(sides.begin(), sides.end());
  return sides;
}

}  // namespace

std::vector<MeshEdge> meshEdges(const Mesh& mesh) {
  std::vector<MeshEdge> edges = polygonSides(mesh);
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

std::vector<int> borderVertices(const Mesh& mesh) {
  const std::vector<MeshEdge> sides = polygonSides(mesh);
  std::vector<int> border;
  for (std::size_t k = 0; k < sides.size();) {
    std::size_t next = k + 1;
    while (next < sides.size() && sides[next] == sides[k]) {
      ++next;
    }
    if (next == k + 1) {
      border.push_back(sides[k][0]);
      border.push_back(sides[k][1]);
    }
    k = next;
  }
  std::sort(border.begin(), border.end());
  border.erase(std::unique(border.begin(), border.end()), border.end());
  return border;
}

std::vector<double> edgeLengthRatios(const Mesh& mesh, const float* xyz) {
  const auto length = [](const float* p, int a, int b) {
    const double dx = p[3 * a] - p[3 * b], dy = p[3 * a + 1] - p[3 * b + 1],
                 dz = p[3 * a + 2] - p[3 * b + 2];
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  };
  std::vector<double> ratios;
  for (const auto& [a, b] : meshEdges(mesh)) {
    const double rest = length(mesh.positions.data(), a, b);
    if (rest > 0.0) {
      ratios.push_back(length(xyz, a, b) / rest);
    }
  }
  return ratios;
}

double medianEdgeScale(const Mesh& mesh, const float* xyz) {
  std::vector<double> ratios = edgeLengthRatios(mesh, xyz);
  if (ratios.empty()) {
    return 0.0;
  }
  std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
  return ratios[ratios.size() / 2];
}

}  // namespace drivenshape
