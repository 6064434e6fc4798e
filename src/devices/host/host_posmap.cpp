// SPDX-License-Identifier: Apache-2.0
// The host reference of the position-map gather (contract: PositionMapBackend in
// position_map.h; the OpenCL twin is kernels/posmap.cl). Plain loops in float, in the same
// order of operations as the kernels, so the two agree to a few ulps.

#include <drivenshape/position_map_backend.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "posmap_checks.h"

namespace drivenshape {
namespace {

struct Vec3 {
  float x, y, z;
};

Vec3 load(const float* data, std::size_t index) {
  return {data[3 * index], data[3 * index + 1], data[3 * index + 2]};
}

void store(float* data, std::size_t index, const Vec3& v) {
  data[3 * index] = v.x;
  data[3 * index + 1] = v.y;
  data[3 * index + 2] = v.z;
}

Vec3 sub(const Vec3& a, const Vec3& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}

/// a + s * b, rounded per operation as the kernel writes it.
Vec3 addScaled(const Vec3& a, float s, const Vec3& b) {
  return {a.x + s * b.x, a.y + s * b.y, a.z + s * b.z};
}

Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

/// v / |v|, or 0 when |v| is 0 (a degenerate normal stays 0 rather than NaN).
Vec3 normalised(const Vec3& v) {
  const float length = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  if (!(length > 0.0f)) {
    return {0.0f, 0.0f, 0.0f};
  }
  return {v.x / length, v.y / length, v.z / length};
}

/// p0 + b1 (p1 - p0) + b2 (p2 - p0) for triangle corners c0 c1 c2 of `values` (3 per vertex).
Vec3 interpolate(const float* values, const int* corners, float b1, float b2) {
  const Vec3 p0 = load(values, static_cast<std::size_t>(corners[0]));
  const Vec3 p1 = load(values, static_cast<std::size_t>(corners[1]));
  const Vec3 p2 = load(values, static_cast<std::size_t>(corners[2]));
  return addScaled(addScaled(p0, b1, sub(p1, p0)), b2, sub(p2, p0));
}

class HostPositionMaps final : public PositionMapBackend {
 public:
  std::string name() const override { return "host"; }

  void upload(const PositionMapTables& tables) override {
    posmap_checks::checkTables(tables);
    mTables = tables;
    mVertexNormals.assign(3 * static_cast<std::size_t>(tables.vertexCount), 0.0f);
    mUploaded = true;
  }

  void evaluate(int frameCount, const float* frames, float* positions, float* normals) override {
    posmap_checks::checkCall(mUploaded, frameCount, frames, positions);
    const std::size_t vertexFloats = 3 * static_cast<std::size_t>(mTables.vertexCount);
    const std::size_t mapFloats = 3 * mTables.texelCount();
    for (int f = 0; f < frameCount; ++f) {
      const float* xyz = frames + static_cast<std::size_t>(f) * vertexFloats;
      float* outP = positions + static_cast<std::size_t>(f) * mapFloats;
      std::fill(outP, outP + mapFloats, 0.0f);
      float* outN = nullptr;
      if (normals != nullptr) {
        outN = normals + static_cast<std::size_t>(f) * mapFloats;
        std::fill(outN, outN + mapFloats, 0.0f);
        vertexNormals(xyz);
      }
      for (std::size_t e = 0; e < mTables.texels.size(); ++e) {
        const int* corners =
            mTables.triangles.data() + 3 * static_cast<std::size_t>(mTables.texelTriangles[e]);
        const float b1 = mTables.texelWeights[2 * e];
        const float b2 = mTables.texelWeights[2 * e + 1];
        const std::size_t texel = static_cast<std::size_t>(mTables.texels[e]);
        store(outP, texel, interpolate(xyz, corners, b1, b2));
        if (outN != nullptr) {
          store(outN, texel, normalised(interpolate(mVertexNormals.data(), corners, b1, b2)));
        }
      }
    }
  }

  std::size_t maxBufferBytes() const override { return std::numeric_limits<std::size_t>::max(); }

 private:
  /// Area-weighted vertex normals of one frame: the sum of the incident triangles' cross
  /// products (twice their area times their unit normal), normalised.
  void vertexNormals(const float* xyz) {
    for (int v = 0; v < mTables.vertexCount; ++v) {
      Vec3 sum{0.0f, 0.0f, 0.0f};
      const int begin = mTables.vertexTriangleStart[static_cast<std::size_t>(v)];
      const int end = mTables.vertexTriangleStart[static_cast<std::size_t>(v) + 1];
      for (int i = begin; i < end; ++i) {
        const int* c =
            mTables.triangles.data() +
            3 * static_cast<std::size_t>(mTables.vertexTriangles[static_cast<std::size_t>(i)]);
        const Vec3 p0 = load(xyz, static_cast<std::size_t>(c[0]));
        const Vec3 n = cross(sub(load(xyz, static_cast<std::size_t>(c[1])), p0),
                             sub(load(xyz, static_cast<std::size_t>(c[2])), p0));
        sum = {sum.x + n.x, sum.y + n.y, sum.z + n.z};
      }
      store(mVertexNormals.data(), static_cast<std::size_t>(v), normalised(sum));
    }
  }

  PositionMapTables mTables;
  std::vector<float> mVertexNormals;
  bool mUploaded = false;
};

}  // namespace

std::unique_ptr<PositionMapBackend> makeHostPositionMaps() {
  return std::make_unique<HostPositionMaps>();
}

}  // namespace drivenshape
