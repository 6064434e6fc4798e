// SPDX-License-Identifier: Apache-2.0
#pragma once

// Point-triangle distance and the local frame of a triangle in double: the host half of
// kernels/closest.cl and kernels/transfer.cl (same formulas, same thresholds), used by the
// candidate search, the host backend and the audit.

#include <algorithm>
#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <correction_types.h>

namespace drivenshape::correction {

/// Squared distance from p to the segment a + t e, t in [0, 1]; sets t. A zero-length segment
/// is the point a.
inline double segmentDistance2(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                               const Eigen::Vector3d& e, double& t) {
  const double ee = e.dot(e);
  double s = 0.0;
  if (ee > 0.0) {
    s = std::min(std::max((p - a).dot(e) / ee, 0.0), 1.0);
  }
  t = s;
  return (p - (a + s * e)).squaredNorm();
}

/// Squared distance from p to triangle (a, b, c); sets (u, v) of the closest point
/// q = a + u (b - a) + v (c - a). The projection if it falls inside, else the closest of the
/// three edges; flat triangles (DS_FLAT_SIN2_DOUBLE) are measured as their edges only.
inline double triangleDistance2(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                const Eigen::Vector3d& b, const Eigen::Vector3d& c, double& u,
                                double& v) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d ap = p - a;
  const Eigen::Vector3d n = ab.cross(ac);
  const double nn = n.dot(n);
  if (nn > DS_FLAT_SIN2_DOUBLE * ab.dot(ab) * ac.dot(ac)) {
    const double su = ap.cross(ac).dot(n) / nn;
    const double sv = ab.cross(ap).dot(n) / nn;
    if (su >= 0.0 && sv >= 0.0 && su + sv <= 1.0) {
      u = su;
      v = sv;
      const double h = ap.dot(n);
      return h * h / nn;
    }
  }
  double t = 0.0;
  double best = segmentDistance2(p, a, ab, t);
  u = t;
  v = 0.0;
  double d2 = segmentDistance2(p, a, ac, t);
  if (d2 < best) {
    best = d2;
    u = 0.0;
    v = t;
  }
  d2 = segmentDistance2(p, b, c - b, t);
  if (d2 < best) {
    best = d2;
    u = 1.0 - t;
    v = t;
  }
  return best;
}

/// The transfer frame at (u, v) of triangle (a, b, c): origin q, e1 = unit first edge,
/// n = unit normal, e2 = n x e1. Returns false (q still set) when the frame is degenerate:
/// zero first edge or flat in the sense of DS_FRAME_SIN2_DOUBLE.
struct LocalFrame {
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
  Eigen::Vector3d e1 = Eigen::Vector3d::Zero();
  Eigen::Vector3d e2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
};

inline bool localFrame(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                       double u, double v, LocalFrame& frame) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  frame.q = a + u * ab + v * ac;
  const Eigen::Vector3d nv = ab.cross(ac);
  const double abab = ab.dot(ab);
  const double nn = nv.dot(nv);
  if (!(abab > 0.0) || !(nn > DS_FRAME_SIN2_DOUBLE * abab * ac.dot(ac))) {
    return false;
  }
  frame.e1 = ab / std::sqrt(abab);
  frame.n = nv / std::sqrt(nn);
  frame.e2 = frame.n.cross(frame.e1);
  return true;
}

/// Vertex `index` of an interleaved float xyz array, in double.
inline Eigen::Vector3d loadPoint(const float* xyz, long index) {
  return Eigen::Vector3f(xyz[3 * index], xyz[3 * index + 1], xyz[3 * index + 2]).cast<double>();
}

}  // namespace drivenshape::correction
