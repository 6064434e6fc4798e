// SPDX-License-Identifier: Apache-2.0
// The host reference of kernels/certificate.cl: per frame the boxes (as dsBvhRefit) and the
// cones (dsCertRefitCones), then the walk of every point (dsCertCheck); src/devices/
// certificate.cpp has the scheme and why it is sound. Same tree, same order, same comparisons,
// in double. Also HostClosest::closestOrClearBlock (host_closest.h), which clears what the
// certificate proves and runs the exact search (host_closest.cpp) on the rest.

#include "host_certificate.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>

#include <drivenshape/error.h>

#include "parallel.h"

#include "certificate.h"
#include "host_closest.h"
#include "triangle_distance.h"

namespace drivenshape::correction {
namespace {

/// At most this many triangles per BVH leaf: the OpenCL backend's.
constexpr int kLeafSize = 4;

/// Whether triangle (a, b, c) is well shaped (DS_CERT_SIN2_DOUBLE); sets its unit normal.
bool unitNormal(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                Eigen::Vector3d& normal) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d n = ab.cross(ac);
  const double nn = n.dot(n);
  if (!(nn > DS_CERT_SIN2_DOUBLE * ab.dot(ab) * ac.dot(ac))) {
    return false;
  }
  normal = n / std::sqrt(nn);
  return true;
}

/// dsCertInFront: well shaped, and p at least `target` in front of the plane.
bool inFront(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
             const Eigen::Vector3d& c, double target) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d n = ab.cross(ac);
  const double nn = n.dot(n);
  const double h = (p - a).dot(n);
  return nn > DS_CERT_SIN2_DOUBLE * ab.dot(ab) * ac.dot(ac) && h > 0.0 &&
         h * h >= target * target * nn;
}

float roundUp(double x) {
  if (!std::isfinite(x)) {
    return std::numeric_limits<float>::infinity();
  }
  float rounded = static_cast<float>(x);
  if (static_cast<double>(rounded) < x) {
    rounded = std::nextafter(rounded, std::numeric_limits<float>::infinity());
  }
  return rounded;
}

Eigen::Vector3d axisOf(const DsCertCone& cone) {
  return Eigen::Vector3d(cone.axis[0], cone.axis[1], cone.axis[2]);
}

/// Every node's box (N x 6) and cone on `pose`, as dsBvhRefit and dsCertRefitCones.
void refit(const BvhTables& bvh, const float* pose, std::vector<float>& boxes,
           std::vector<DsCertCone>& cones) {
  boxes.assign(bvh.nodes.size() * 6, 0.0f);
  cones.assign(bvh.nodes.size(), DsCertCone{});
  for (int level = bvh.depth() - 1; level >= 0; --level) {
    for (int n = bvh.levelStart[static_cast<std::size_t>(level)];
         n < bvh.levelStart[static_cast<std::size_t>(level) + 1]; ++n) {
      const DsBvhNode& node = bvh.nodes[static_cast<std::size_t>(n)];
      float* box = &boxes[6 * static_cast<std::size_t>(n)];
      DsCertCone& cone = cones[static_cast<std::size_t>(n)];
      cone = DsCertCone{{0.0f, 0.0f, 0.0f},
                        std::numeric_limits<float>::infinity(),
                        std::numeric_limits<float>::infinity(),
                        0.0f,
                        0.0f,
                        0.0f};
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      bool usable = true;
      if (node.count > 0) {
        std::fill(box, box + 3, std::numeric_limits<float>::infinity());
        std::fill(box + 3, box + 6, -std::numeric_limits<float>::infinity());
        for (int k = node.first; k < node.first + node.count; ++k) {
          const std::int32_t* slot = &bvh.leafTriangles[4 * static_cast<std::size_t>(k)];
          for (int j = 0; j < 3; ++j) {
            const float* x = pose + 3 * static_cast<std::size_t>(slot[j]);
            for (int a = 0; a < 3; ++a) {
              box[a] = std::fmin(box[a], x[a]);
              box[3 + a] = std::fmax(box[3 + a], x[a]);
            }
          }
          Eigen::Vector3d normal;
          if (usable && unitNormal(loadPoint(pose, slot[0]), loadPoint(pose, slot[1]),
                                   loadPoint(pose, slot[2]), normal)) {
            sum += normal;
          } else {
            usable = false;
          }
        }
      } else {
        const float* left = &boxes[6 * static_cast<std::size_t>(node.left)];
        const float* right = &boxes[6 * static_cast<std::size_t>(node.right)];
        for (int a = 0; a < 3; ++a) {
          box[a] = std::fmin(left[a], right[a]);
          box[3 + a] = std::fmax(left[3 + a], right[3 + a]);
        }
        const DsCertCone& l = cones[static_cast<std::size_t>(node.left)];
        const DsCertCone& r = cones[static_cast<std::size_t>(node.right)];
        usable = std::isfinite(l.spread) && std::isfinite(r.spread);
        sum = axisOf(l) + axisOf(r);
      }
      const double norm = sum.norm();
      if (!usable || !(norm > 0.0)) {
        continue;
      }
      const Eigen::Vector3d unit = sum / norm;
      for (int a = 0; a < 3; ++a) {
        cone.axis[a] = static_cast<float>(unit[a]);
      }
      const Eigen::Vector3d axis = axisOf(cone);
      double spread = 0.0;
      double offset = -std::numeric_limits<double>::infinity();
      if (node.count > 0) {
        for (int k = node.first; k < node.first + node.count; ++k) {
          const std::int32_t* slot = &bvh.leafTriangles[4 * static_cast<std::size_t>(k)];
          Eigen::Vector3d normal;
          unitNormal(loadPoint(pose, slot[0]), loadPoint(pose, slot[1]), loadPoint(pose, slot[2]),
                     normal);
          spread = std::max(spread, (normal - axis).norm());
          for (int j = 0; j < 3; ++j) {
            offset = std::max(offset, axis.dot(loadPoint(pose, slot[j])));
          }
        }
        spread += DS_CERT_CONE_SLACK_DOUBLE;
      } else {
        for (const int child : {node.left, node.right}) {
          const DsCertCone& c = cones[static_cast<std::size_t>(child)];
          spread = std::max(spread, (axisOf(c) - axis).norm() + static_cast<double>(c.spread));
          const Eigen::Vector3d turn = axis - axisOf(c);
          const float* childBox = &boxes[6 * static_cast<std::size_t>(child)];
          double support = 0.0;
          for (int a = 0; a < 3; ++a) {
            support += std::max(turn[a] * static_cast<double>(childBox[a]),
                                turn[a] * static_cast<double>(childBox[3 + a]));
          }
          offset = std::max(offset, static_cast<double>(c.offset) + support);
        }
      }
      cone.offset = roundUp(offset);
      cone.spread = spread < 2.0 ? roundUp(spread) : std::numeric_limits<float>::infinity();
    }
  }
}

/// dsCertOpen: whether the node (box, cone, a triangle under it) must be opened for p; lowers
/// U (core2 = U^2, limit = U + margin) and moves the witness to `triangle` when the box's
/// farthest point bounds the distance better; distance gets the box's squared distance.
bool openNode(const Eigen::Vector3d& p, const float* box, const DsCertCone& cone, int triangle,
              double target, double margin, double& limit, double& core2, int& witness,
              double& distance) {
  distance = 0.0;
  double far2 = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double low = box[a];
    const double high = box[3 + a];
    const double e = std::max(std::max(low - p[a], p[a] - high), 0.0);
    distance += e * e;
    const double f = std::max(std::fabs(p[a] - low), std::fabs(p[a] - high));
    far2 += f * f;
  }
  if (distance > limit * limit) {
    return false;
  }
  if (far2 < core2) {
    core2 = far2;
    limit = std::sqrt(far2) + margin;
    witness = triangle;
  }
  const double front =
      static_cast<double>(cone.axis[0]) * p.x() + static_cast<double>(cone.axis[1]) * p.y() +
      static_cast<double>(cone.axis[2]) * p.z() - static_cast<double>(cone.offset) - target;
  // Only the triangles within the limit must pass: |p - x| <= min(far, limit) for their
  // nearest point x.
  const double spread = cone.spread;
  const double reach2 = std::min(far2, limit * limit);
  return !(std::isfinite(spread) && front >= 0.0 && front * front >= spread * spread * reach2);
}

/// What the walks of one frame read: the tree with its boxes and cones refitted on the pose,
/// the posed triangles, and the distance in front of the surface a point must prove.
struct CertWalk {
  const BvhTables& bvh;
  const std::int32_t* triangles;      ///< T x 3
  const std::int32_t* nodeTriangles;  ///< N, nodeTriangles()
  const float* pose;                  ///< 3Vp
  const std::vector<float>& boxes;    ///< N x 6
  const std::vector<DsCertCone>& cones;
  double margin;
  double target;       ///< clearance + margin
  double reachMargin;  ///< margin + 2 reach: the limit's margin (the answer holds within reach)

  Eigen::Vector3d corner(int t, int k) const {
    return loadPoint(pose,
                     triangles[3 * static_cast<std::size_t>(t) + static_cast<std::size_t>(k)]);
  }
  const DsBvhNode& node(int n) const { return bvh.nodes[static_cast<std::size_t>(n)]; }
  /// A leaf triangle: its three vertices, then its index.
  const std::int32_t* slot(int k) const {
    return &bvh.leafTriangles[4 * static_cast<std::size_t>(k)];
  }
};

/// The first upper bound U^2 of p's distance to the surface: the squared distance to the seed
/// triangle, `witness`.
double upperBound2(const CertWalk& w, const Eigen::Vector3d& p, int witness) {
  double u = 0.0;
  double v = 0.0;
  return triangleDistance2(p, w.corner(witness, 0), w.corner(witness, 1), w.corner(witness, 2), u,
                           v);
}

/// The first leaf of the walk (nearer child first: the leaf of a greedy descent from the root):
/// its triangles' distances lower U (core2 = U^2, limit = U + reach margin) and move the witness
/// to the nearest, before any of them is plane-tested.
void measureLeaf(const CertWalk& w, const Eigen::Vector3d& p, const DsBvhNode& leaf, double& limit,
                 double& core2, int& witness) {
  double u = 0.0;
  double v = 0.0;
  for (int k = leaf.first; k < leaf.first + leaf.count; ++k) {
    const std::int32_t* slot = w.slot(k);
    const double d2 = triangleDistance2(p, loadPoint(w.pose, slot[0]), loadPoint(w.pose, slot[1]),
                                        loadPoint(w.pose, slot[2]), u, v);
    if (d2 < core2) {
      core2 = d2;
      witness = slot[3];
      limit = std::min(limit, std::sqrt(d2) + w.reachMargin);
    }
  }
}

/// A leaf of the walk: whether p is the target in front of each of its triangles whose box
/// lies within `limit`.
bool leafInFront(const CertWalk& w, const Eigen::Vector3d& p, const DsBvhNode& leaf, double limit) {
  bool pass = true;
  for (int k = leaf.first; k < leaf.first + leaf.count && pass; ++k) {
    const std::int32_t* slot = w.slot(k);
    const Eigen::Vector3d a = loadPoint(w.pose, slot[0]);
    const Eigen::Vector3d b = loadPoint(w.pose, slot[1]);
    const Eigen::Vector3d c = loadPoint(w.pose, slot[2]);
    const Eigen::Vector3d e =
        (a.cwiseMin(b).cwiseMin(c) - p).cwiseMax(p - a.cwiseMax(b).cwiseMax(c)).cwiseMax(0.0);
    const double d2 = e.dot(e);
    if (d2 > limit * limit) {
      continue;
    }
    pass = inFront(p, a, b, c, w.target);
  }
  return pass;
}

/// What one walk of dsCertCheck carries and lowers: U (core2 = U^2, limit = U + reach margin)
/// and the witness, and where it stands on the first leaf, whose triangles' distances lower U
/// before anything is plane-tested (measureLeaf).
struct WalkState {
  double limit = 0.0;
  double core2 = 0.0;
  int witness = -1;
  bool measureCovered = false;  ///< descend a covered nearer child for the first leaf
  bool measure = true;          ///< no leaf reached yet
  bool covered = false;         ///< in a covered node, descending for the first leaf only
  bool skipped = false;         ///< a covered nearer child passed by before the first leaf
};

/// An inner node of the walk: opens both children for p (openNode) and returns the nearer
/// open one within `limit` (-1 when none), pushing the farther onto `stack` when both are. The
/// first leaf: in a covered node, the nearer child; a covered nearer child before the first leaf
/// is descended (the other pushed) with measureCovered, else only noted (skipped).
int openChildren(const CertWalk& w, const Eigen::Vector3d& p, const DsBvhNode& inner, WalkState& s,
                 std::vector<std::pair<int, double>>& stack) {
  const int child[2] = {inner.left, inner.right};
  double distances[2];
  bool opened[2];
  for (int side = 0; side < 2; ++side) {
    const std::size_t c = static_cast<std::size_t>(child[side]);
    opened[side] = openNode(p, &w.boxes[6 * c], w.cones[c], w.nodeTriangles[c], w.target,
                            w.reachMargin, s.limit, s.core2, s.witness, distances[side]);
  }
  const int nearSide = distances[0] <= distances[1] ? 0 : 1;
  if (s.covered) {
    return child[nearSide];
  }
  const double limit2 = s.limit * s.limit;
  int next = -1;
  if (opened[nearSide] && distances[nearSide] <= limit2) {
    next = child[nearSide];
  }
  if (opened[1 - nearSide] && distances[1 - nearSide] <= limit2) {
    if (next < 0) {
      next = child[1 - nearSide];
    } else {
      stack.emplace_back(child[1 - nearSide], distances[1 - nearSide]);
    }
  }
  if (s.measure && !opened[nearSide] && distances[nearSide] <= limit2) {
    s.skipped = true;
    if (s.measureCovered) {
      if (next >= 0) {
        stack.emplace_back(next, distances[next == child[0] ? 0 : 1]);
      }
      next = child[nearSide];
      s.covered = true;
    }
  }
  return next;
}

/// dsCertWalk from the root: false as soon as a triangle within reach does not have p the
/// target in front of it. Opening nodes and the first leaf can lower the bound and move the
/// witness.
bool walkClears(const CertWalk& w, const Eigen::Vector3d& p, WalkState& s,
                std::vector<std::pair<int, double>>& stack) {
  double distance = 0.0;
  bool pass = true;
  s.measure = true;
  s.covered = false;
  int node = openNode(p, w.boxes.data(), w.cones[0], w.nodeTriangles[0], w.target, w.reachMargin,
                      s.limit, s.core2, s.witness, distance)
                 ? 0
                 : -1;
  stack.clear();
  while (node >= 0 && pass) {
    const DsBvhNode& current = w.node(node);
    int next = -1;
    if (current.count > 0) {
      if (s.measure) {
        measureLeaf(w, p, current, s.limit, s.core2, s.witness);
        s.measure = false;
      }
      pass = s.covered || leafInFront(w, p, current, s.limit);
      s.covered = false;
    } else {
      next = openChildren(w, p, current, s, stack);
    }
    while (next < 0 && !stack.empty()) {
      if (stack.back().second <= s.limit * s.limit) {
        next = stack.back().first;
      }
      stack.pop_back();
    }
    node = next;
  }
  return pass;
}

/// The certificate of point p, starting from triangle `seed`: true when p is proven the target
/// in front of the surface, with `hit` the witness triangle at its centroid. The walk descends
/// covered nodes for the first leaf only when it failed without (dsCertCheck).
bool certifyPoint(const CertWalk& w, const Eigen::Vector3d& p, int seed,
                  std::vector<std::pair<int, double>>& stack, SurfaceHit& hit) {
  WalkState s;
  s.witness = seed;
  s.core2 = upperBound2(w, p, seed);
  s.limit = std::sqrt(s.core2) + w.reachMargin;
  bool cleared = walkClears(w, p, s, stack);
  if (!cleared && s.skipped) {
    s.measureCovered = true;
    cleared = walkClears(w, p, s, stack);
  }
  const int witness = s.witness;
  const bool pass = cleared && inFront(p, w.corner(witness, 0), w.corner(witness, 1),
                                       w.corner(witness, 2), w.target);
  if (!pass) {
    return false;
  }
  hit.triangle = witness;
  hit.u = DS_CERT_THIRD;
  hit.v = DS_CERT_THIRD;
  const Eigen::Vector3d a = w.corner(witness, 0);
  const Eigen::Vector3d centroid = a + static_cast<double>(hit.u) * (w.corner(witness, 1) - a) +
                                   static_cast<double>(hit.v) * (w.corner(witness, 2) - a);
  hit.distance2 = static_cast<float>((p - centroid).squaredNorm());
  return true;
}

}  // namespace

void HostCertificate::setSurface(const Mesh& driver, const BindingMask& mask, double sceneScale) {
  mVertexCount = driver.vertexCount();
  mPointCount = mask.drivenVertexCount();
  mMargin = DS_CERT_MARGIN_DOUBLE * sceneScale;
  mTriangles.resize(3 * static_cast<std::size_t>(driver.triangleCount()));
  for (int t = 0; t < driver.triangleCount(); ++t) {
    for (int k = 0; k < 3; ++k) {
      mTriangles[3 * static_cast<std::size_t>(t) + static_cast<std::size_t>(k)] =
          driver.triangles(t, k);
    }
  }
  mBvh = buildBvh(driver, mask, kLeafSize);
  mEnabled = certifiable(mBvh, driver.triangleCount());
  mNodeTriangles = nodeTriangles(mBvh);
  mSeeds.clear();
}

void HostCertificate::remember(const SurfaceHit* lastFrame) {
  mSeeds.resize(static_cast<std::size_t>(mPointCount));
  for (int i = 0; i < mPointCount; ++i) {
    mSeeds[static_cast<std::size_t>(i)] = lastFrame[i].triangle;
  }
}

void HostCertificate::clear(int frameCount, const float* poses, const float* points,
                            float clearance, float reach, bool seedFromHits, SurfaceHit* hits,
                            std::uint8_t* active, int* cleared, int threads) {
  const std::size_t items = static_cast<std::size_t>(frameCount) * mPointCount;
  if (!mEnabled || items == 0) {
    return;
  }
  if (mSeeds.empty()) {
    seedTriangles(mBvh, mTriangles.data(), poses, points, mSeeds);
  }
  const std::size_t poseValues = 3 * static_cast<std::size_t>(mVertexCount);
  // The kernel's parameters are floats.
  const double margin = static_cast<double>(static_cast<float>(mMargin));
  const double target = static_cast<double>(clearance) + margin;
  const double reachMargin = margin + 2.0 * static_cast<double>(reach);
  parallelFor(frameCount, threads, [&](int f) {
    const float* pose = poses + static_cast<std::size_t>(f) * poseValues;
    std::vector<float> boxes;
    std::vector<DsCertCone> cones;
    refit(mBvh, pose, boxes, cones);
    const CertWalk walk{
        mBvh,   mTriangles.data(), mNodeTriangles.data(), pose, boxes, cones, margin,
        target, reachMargin};
    std::vector<std::pair<int, double>> stack;
    int count = 0;
    for (int i = 0; i < mPointCount; ++i) {
      const std::size_t item = static_cast<std::size_t>(f) * mPointCount + i;
      if (active[item] == 0) {
        continue;
      }
      const Eigen::Vector3d p = loadPoint(points, static_cast<long>(item));
      SurfaceHit hit;
      const int seed = seedFromHits ? hits[item].triangle : mSeeds[static_cast<std::size_t>(i)];
      if (!certifyPoint(walk, p, seed, stack, hit)) {
        continue;
      }
      hits[item] = hit;
      active[item] = 0;
      ++count;
    }
    cleared[f] += count;
  });
}

}  // namespace drivenshape::correction

namespace drivenshape {

void HostClosest::closestOrClearBlock(int frameCount, DeviceArray& poses, DeviceArray& points,
                                      float clearance, DeviceArray& hits, int* cleared,
                                      DeviceArray* answered, bool keep, float reach) {
  mSearch.checkChunk("closest triangle", frameCount, true);
  correction::checkOffset(clearance);
  correction::checkOffset(reach);
  const float* posesIn = poses.read<float>();
  const float* pointsIn = points.read<float>();
  correction::checkFinite("closest triangle", "driver vertex", frameCount, mSearch.vertexCount(),
                          posesIn);
  correction::checkFinite("closest triangle", "driven point", frameCount, mSearch.pointCount(),
                          pointsIn);
  const int pointCount = mSearch.pointCount();
  const std::size_t items = static_cast<std::size_t>(frameCount) * pointCount;
  const bool kept = keep && answered != nullptr;
  SurfaceHit* out = kept ? hits.modify<SurfaceHit>() : hits.write<SurfaceHit>();
  mActive.assign(items, 1);
  mCleared.assign(static_cast<std::size_t>(frameCount), 0);
  if (kept) {
    const std::int32_t* before = answered->read<std::int32_t>();
    for (std::size_t k = 0; k < items; ++k) {
      if (before[k] != 0) {
        mActive[k] = 0;
        ++mCleared[k / static_cast<std::size_t>(pointCount)];
      }
    }
  }
  mCertificate.clear(frameCount, posesIn, pointsIn, clearance, reach, kept, out, mActive.data(),
                     mCleared.data(), mSearch.threads());
  if (cleared != nullptr) {
    std::copy(mCleared.begin(), mCleared.end(), cleared);
  }
  exact(frameCount, posesIn, pointsIn, out, mActive.data());
  if (answered != nullptr) {
    std::int32_t* after = answered->write<std::int32_t>();
    for (std::size_t k = 0; k < items; ++k) {
      after[k] = mActive[k] == 0 ? 1 : 0;
    }
  }
  if (frameCount > 0) {
    mCertificate.remember(out + static_cast<std::size_t>(frameCount - 1) * pointCount);
  }
}

}  // namespace drivenshape
