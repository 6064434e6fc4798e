// SPDX-License-Identifier: Apache-2.0
#include "correction_test_util.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

#include <drivenshape/point_cache.h>

#include "test_support.h"

namespace drivenshape::testing {
namespace {

Eigen::Vector3d vertex(const float* xyz, int v) {
  return Eigen::Vector3d(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]);
}

double segmentDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& x,
                       const Eigen::Vector3d& y) {
  const Eigen::Vector3d e = y - x;
  const double ee = e.squaredNorm();
  const double t = ee > 0.0 ? std::clamp((p - x).dot(e) / ee, 0.0, 1.0) : 0.0;
  return (p - x - t * e).norm();
}

double cross2(double ax, double ay, double bx, double by) {
  return ax * by - ay * bx;
}

}  // namespace

double oracleTriangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                              const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const double edges =
      std::min({segmentDistance(p, a, b), segmentDistance(p, b, c), segmentDistance(p, c, a)});
  // Longest edge x -> y, opposite vertex z.
  std::array<Eigen::Vector3d, 3> v = {a, b, c};
  int longest = 0;
  double longestLength = -1.0;
  for (int k = 0; k < 3; ++k) {
    const double length = (v[(k + 1) % 3] - v[k]).norm();
    if (length > longestLength) {
      longestLength = length;
      longest = k;
    }
  }
  const Eigen::Vector3d x = v[longest];
  const Eigen::Vector3d y = v[(longest + 1) % 3];
  const Eigen::Vector3d z = v[(longest + 2) % 3];
  if (!(longestLength > 0.0)) {
    return edges;
  }
  const Eigen::Vector3d e1 = (y - x) / longestLength;
  const Eigen::Vector3d w = (z - x) - (z - x).dot(e1) * e1;
  const double height = w.norm();
  if (height <= 1e-12 * longestLength) {
    return edges;
  }
  const Eigen::Vector3d e2 = w / height;
  const Eigen::Vector3d n = e1.cross(e2);
  const double px = (p - x).dot(e1);
  const double py = (p - x).dot(e2);
  const double zx = (z - x).dot(e1);
  const double zy = height;
  // Triangle (0,0), (L,0), (zx,zy) is counter-clockwise; inside = left of every edge.
  const bool inside = cross2(longestLength, 0.0, px, py) >= 0.0 &&
                      cross2(zx - longestLength, zy, px - longestLength, py) >= 0.0 &&
                      cross2(-zx, -zy, px - zx, py - zy) >= 0.0;
  if (inside) {
    return std::min(edges, std::fabs((p - x).dot(n)));
  }
  return edges;
}

double bruteForceDistance(const Mesh& mesh, const float* pose, const float* point,
                          const std::vector<int>& allowed) {
  const Eigen::Vector3d p = vertex(point, 0);
  double best = std::numeric_limits<double>::infinity();
  auto visit = [&](int t) {
    best = std::min(best, oracleTriangleDistance(p, vertex(pose, mesh.triangles(t, 0)),
                                                 vertex(pose, mesh.triangles(t, 1)),
                                                 vertex(pose, mesh.triangles(t, 2))));
  };
  if (allowed.empty()) {
    for (int t = 0; t < mesh.triangleCount(); ++t) {
      visit(t);
    }
  } else {
    for (int t : allowed) {
      visit(t);
    }
  }
  return best;
}

double hitDistance(const Mesh& mesh, const float* pose, const float* point, const SurfaceHit& hit) {
  const Eigen::Vector3d a = vertex(pose, mesh.triangles(hit.triangle, 0));
  const Eigen::Vector3d b = vertex(pose, mesh.triangles(hit.triangle, 1));
  const Eigen::Vector3d c = vertex(pose, mesh.triangles(hit.triangle, 2));
  const Eigen::Vector3d q = a + double(hit.u) * (b - a) + double(hit.v) * (c - a);
  return (vertex(point, 0) - q).norm();
}

double sceneScale(const float* xyz, int count, const float* more, int moreCount) {
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d high = -low;
  double magnitude = 0.0;
  auto visit = [&](const float* data, int n) {
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d p = vertex(data, i);
      low = low.cwiseMin(p);
      high = high.cwiseMax(p);
      magnitude = std::max(magnitude, p.cwiseAbs().maxCoeff());
    }
  };
  visit(xyz, count);
  if (more != nullptr) {
    visit(more, moreCount);
  }
  return std::max((high - low).norm(), magnitude);
}

Mesh makeMesh(const std::vector<float>& xyz, const std::vector<std::vector<int>>& faces) {
  Mesh mesh;
  mesh.positions = Eigen::Map<const Positions>(xyz.data(), static_cast<long>(xyz.size() / 3), 3);
  mesh.faceStart.push_back(0);
  for (const std::vector<int>& face : faces) {
    mesh.faceVertices.insert(mesh.faceVertices.end(), face.begin(), face.end());
    mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
    mesh.faceGroup.push_back(0);
  }
  mesh.groupNames = {"default"};
  mesh.triangulate();
  return mesh;
}

Mesh randomSoup(std::mt19937& rng, int vertexCount, int triangleCount) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<float> xyz;
  auto add = [&](const Eigen::Vector3f& p) {
    xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    return static_cast<int>(xyz.size() / 3) - 1;
  };
  auto at = [&](int v) { return Eigen::Vector3f(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]); };
  auto randomUnit = [&]() {
    Eigen::Vector3f d;
    do {
      d = Eigen::Vector3f(unit(rng), unit(rng), unit(rng)) * 2.0f - Eigen::Vector3f::Ones();
    } while (d.norm() < 0.1f || d.norm() > 1.0f);
    return Eigen::Vector3f(d.normalized());
  };
  for (int v = 0; v < vertexCount; ++v) {
    add(Eigen::Vector3f(unit(rng), unit(rng), unit(rng)));
  }
  std::uniform_int_distribution<int> pick(0, vertexCount - 1);
  std::vector<std::vector<int>> faces;
  for (int t = 0; t < triangleCount; ++t) {
    const int kind = t % 16;
    const int a = pick(rng);
    if (kind < 6) {
      // Small, well-shaped triangle near a random vertex.
      const float size = 0.02f + 0.1f * unit(rng);
      faces.push_back({a, add(at(a) + size * randomUnit()), add(at(a) + size * randomUnit())});
    } else if (kind < 10) {
      // Random triplet: large, often long and thin.
      faces.push_back({a, pick(rng), pick(rng)});
    } else if (kind < 14) {
      // Sliver: c near the segment ab, height 1e-2 .. 1e-4 of |ab|.
      int b = pick(rng);
      while (b == a) {
        b = pick(rng);
      }
      const Eigen::Vector3f ab = at(b) - at(a);
      const float height = ab.norm() * std::pow(10.0f, -2.0f - 2.0f * unit(rng));
      const Eigen::Vector3f side = ab.cross(randomUnit()).normalized();
      faces.push_back({a, b, add(at(a) + unit(rng) * ab + height * side)});
    } else if (kind == 14) {
      // Zero-area: a repeated vertex, or all three vertices equal.
      faces.push_back(t % 32 == 14 ? std::vector<int>{a, a, pick(rng)} : std::vector<int>{a, a, a});
    } else {
      // Zero-area to float rounding: c on the segment ab.
      const int b = pick(rng);
      faces.push_back({a, b, add(at(a) + 0.5f * (at(b) - at(a)))});
    }
  }
  return makeMesh(xyz, faces);
}

std::vector<float> randomPoints(std::mt19937& rng, const Mesh& mesh, const float* pose, int count) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::uniform_int_distribution<int> pickTriangle(0, mesh.triangleCount() - 1);
  std::vector<float> out;
  for (int i = 0; i < count; ++i) {
    Eigen::Vector3f p;
    const Eigen::Vector3f direction =
        (Eigen::Vector3f(unit(rng), unit(rng), unit(rng)) - Eigen::Vector3f::Constant(0.5f))
            .normalized();
    switch (i % 4) {
      case 0:
      case 1: {
        // On or near a triangle (offsets 1e-6 .. 1e-1).
        const int t = pickTriangle(rng);
        float u = unit(rng);
        float v = unit(rng);
        if (u + v > 1.0f) {
          u = 1.0f - u;
          v = 1.0f - v;
        }
        const Eigen::Vector3f a(&pose[3 * mesh.triangles(t, 0)]);
        const Eigen::Vector3f b(&pose[3 * mesh.triangles(t, 1)]);
        const Eigen::Vector3f c(&pose[3 * mesh.triangles(t, 2)]);
        const float offset = i % 8 == 0 ? 0.0f : std::pow(10.0f, -6.0f + 5.0f * unit(rng));
        p = a + u * (b - a) + v * (c - a) + offset * direction;
        break;
      }
      case 2:
        p = Eigen::Vector3f(unit(rng), unit(rng), unit(rng)) * 2.0f -
            Eigen::Vector3f::Constant(0.5f);
        break;
      default:
        p = Eigen::Vector3f::Constant(0.5f) + (2.0f + 98.0f * unit(rng)) * direction;
        break;
    }
    out.insert(out.end(), {p.x(), p.y(), p.z()});
  }
  return out;
}

Mesh subdividedCube(int n) {
  std::vector<float> xyz;
  std::vector<std::vector<int>> faces;
  // For each face: an axis, a sign, and two in-plane axes such that (u x v) points outward.
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign = -1; sign <= 1; sign += 2) {
      int uAxis = (axis + 1) % 3;
      int vAxis = (axis + 2) % 3;
      if (sign < 0) {
        std::swap(uAxis, vAxis);
      }
      const int first = static_cast<int>(xyz.size() / 3);
      for (int j = 0; j <= n; ++j) {
        for (int i = 0; i <= n; ++i) {
          float p[3];
          p[axis] = static_cast<float>(sign);
          p[uAxis] = -1.0f + 2.0f * static_cast<float>(i) / static_cast<float>(n);
          p[vAxis] = -1.0f + 2.0f * static_cast<float>(j) / static_cast<float>(n);
          xyz.insert(xyz.end(), {p[0], p[1], p[2]});
        }
      }
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          const int v00 = first + j * (n + 1) + i;
          faces.push_back({v00, v00 + 1, v00 + n + 2, v00 + n + 1});
        }
      }
    }
  }
  // Weld the duplicated border vertices so that the cube is closed.
  std::vector<int> weld(xyz.size() / 3);
  std::vector<float> welded;
  for (std::size_t v = 0; v < weld.size(); ++v) {
    int found = -1;
    for (std::size_t w = 0; w < welded.size() / 3 && found < 0; ++w) {
      if (welded[3 * w] == xyz[3 * v] && welded[3 * w + 1] == xyz[3 * v + 1] &&
          welded[3 * w + 2] == xyz[3 * v + 2]) {
        found = static_cast<int>(w);
      }
    }
    if (found < 0) {
      found = static_cast<int>(welded.size() / 3);
      welded.insert(welded.end(), {xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]});
    }
    weld[v] = found;
  }
  for (std::vector<int>& face : faces) {
    for (int& v : face) {
      v = weld[static_cast<std::size_t>(v)];
    }
  }
  return makeMesh(welded, faces);
}

PosedScene randomSoupScene(std::uint32_t seed, int vertexCount, int triangleCount, float jitter,
                           int frameCount, int pointCount) {
  std::mt19937 rng(seed);
  PosedScene scene;
  scene.mesh = randomSoup(rng, vertexCount, triangleCount);
  scene.frameCount = frameCount;
  scene.pointCount = pointCount;
  std::normal_distribution<float> move(0.0f, jitter);
  for (int f = 0; f < frameCount; ++f) {
    std::vector<float> pose = flatPositions(scene.mesh);
    if (f > 0) {
      for (float& x : pose) {
        x += move(rng);
      }
    }
    const std::vector<float> points = randomPoints(rng, scene.mesh, pose.data(), pointCount);
    scene.poses.insert(scene.poses.end(), pose.begin(), pose.end());
    scene.points.insert(scene.points.end(), points.begin(), points.end());
  }
  return scene;
}

BindingMask randomClassMask(const Mesh& mesh, int pointCount, int single, std::mt19937& rng) {
  std::vector<std::vector<int>> classes(3);
  std::bernoulli_distribution half(0.5);
  for (int t = 0; t < mesh.triangleCount(); ++t) {
    classes[half(rng) ? 0 : 1].push_back(t);
  }
  classes[2] = {single};
  std::vector<int> vertexClass(static_cast<std::size_t>(pointCount));
  for (int i = 0; i < pointCount; ++i) {
    vertexClass[static_cast<std::size_t>(i)] = i % 4 - 1;
  }
  return BindingMask(vertexClass, classes);
}

DegenerateFrames degenerateFrames() {
  DegenerateFrames out;
  out.from = {0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 0, 0, 6, 0, 0};
  out.mesh = makeMesh(out.from, {{0, 1, 1}, {0, 1, 2}, {3, 4, 4}});
  out.to = {1, 1, 1, 1, 2, 1, 0, 1, 1, 9, 9, 9, 9, 9, 9};
  out.points = {0.5f, 0.2f, 0.3f, 0.2f, 0.2f, 0.5f, 5.5f, 1.0f, 0.0f};
  out.hits = {{0, 0.5f, 0.0f, 0.0f}, {1, 0.2f, 0.2f, 0.0f}, {2, 0.5f, 0.0f, 0.0f}};
  return out;
}

SleeveData loadSleeve(const std::vector<int>& frameIndices) {
  SleeveData data;
  const std::string dir = dataDir() + "/sleeve/";
  data.driver = readObj(dir + "driver_rest.obj");
  data.driven = readObj(dir + "driven_rest.obj");
  const auto driverCache = openPc2(dir + "test.driver.pc2");
  const auto drivenCache = openPc2(dir + "test.driven.pc2");
  const std::vector<int> available = driverCache->frames();
  for (int index : frameIndices) {
    data.frames.push_back(available.at(static_cast<std::size_t>(index)));
  }
  data.poses = readFrames(*driverCache, data.frames);
  data.points = readFrames(*drivenCache, data.frames);
  return data;
}

PosedScene restAndFrames(const SleeveData& sleeve) {
  PosedScene scene;
  scene.mesh = sleeve.driver;
  scene.frameCount = 1 + static_cast<int>(sleeve.frames.size());
  scene.pointCount = sleeve.driven.vertexCount();
  scene.poses = flatPositions(sleeve.driver);
  scene.points = flatPositions(sleeve.driven);
  scene.poses.insert(scene.poses.end(), sleeve.poses.begin(), sleeve.poses.end());
  scene.points.insert(scene.points.end(), sleeve.points.begin(), sleeve.points.end());
  return scene;
}

std::vector<SurfaceHit> closestHits(ClosestBackend& backend, const Mesh& mesh,
                                    const BindingMask& mask, int frameCount, const float* poses,
                                    const float* points) {
  backend.setSurface(mesh, mask);
  std::vector<SurfaceHit> hits(static_cast<std::size_t>(frameCount) *
                               static_cast<std::size_t>(mask.drivenVertexCount()));
  backend.closest(frameCount, poses, points, hits.data());
  return hits;
}

std::vector<float> flatPositions(const Mesh& mesh) {
  return std::vector<float>(mesh.positions.data(), mesh.positions.data() + 3 * mesh.vertexCount());
}

std::vector<float> rigidlyMoved(const std::vector<float>& xyz, const Eigen::Matrix3d& rotation,
                                const Eigen::Vector3d& translation) {
  std::vector<float> out(xyz.size());
  for (std::size_t i = 0; i < xyz.size(); i += 3) {
    const Eigen::Vector3d p =
        rotation * Eigen::Vector3d(xyz[i], xyz[i + 1], xyz[i + 2]) + translation;
    out[i] = static_cast<float>(p.x());
    out[i + 1] = static_cast<float>(p.y());
    out[i + 2] = static_cast<float>(p.z());
  }
  return out;
}

double maxPointError(const std::vector<float>& a, const std::vector<float>& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size(); i += 3) {
    const Eigen::Vector3d d(a[i] - b[i], a[i + 1] - b[i + 1], a[i + 2] - b[i + 2]);
    worst = std::max(worst, d.norm());
  }
  return worst;
}

}  // namespace drivenshape::testing
