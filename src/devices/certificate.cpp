// SPDX-License-Identifier: Apache-2.0
// The clearance certificate: exact closest points, searched only where they can matter.
//
// The penetration resolution and the inside audit need, per cloth point p of a frame, only two
// verdicts from its exact closest point q* (ClosestBackend::resolve, countInside): is the
// signed distance below the skin offset (move p), is it negative (count p inside). A point
// whose signed distance is provably at least `clearance` (the offset, or 0 for a count) gets
// both verdicts without its closest triangle: it stays, and it is outside. The certificate
// proves that for most points with a short walk of the BVH that measures no distance but one,
// and the exact search (kernels/bvh.cl) runs on the others.
//
// A distance bound alone cannot do this: a point deep inside a limb is far from every triangle
// and still inside, and where limbs cross (or the driver is open) the side can flip without the
// distance ever getting small. The certificate therefore proves the side too, from the normals.
//
// Scheme, per chunk of F frames (on the device; host reference in
// src/devices/host/host_certificate.cpp), on the BVH of the search (src/database/bvh.cpp):
//   1. Cones (dsCertRefitCones, one launch per depth after dsBvhRefit): every node on every
//      frame gets an axis a_n, a spread e_n >= |n_t - a_n| for the unit normal n_t of every
//      triangle t under it and an offset o_n >= a_n . x for every point x of those triangles
//      (leaves from their triangles, inner nodes from their children by the triangle inequality
//      and the children's boxes; spread INFINITY when a triangle is not well shaped,
//      DS_CERT_SIN2_*).
//   2. Check (dsCertCheck, one item per frame and point p): limit = U + m with U an upper bound
//      of the closest distance D*: the distance from p to its seed triangle (the previous
//      block's hit, as for the search; with `keep`, the item's own hit of the call before,
//      made before the stage between moved p a little), lowered during the walk to the
//      farthest point from p of any box seen (every box holds a triangle) and to the nearest
//      triangle of the first leaf reached (measured before its plane tests); target =
//      clearance + m, m = DS_CERT_MARGIN_* x S. Walk the tree from the root, nearer child first:
//        - a node whose box is farther than `limit` is skipped;
//        - a node whose cone proves front_n(p) = a_n . p - o_n - e_n * min(the box's farthest
//          point from p, limit) >= target is skipped ("covered");
//        - otherwise its children are visited, or, at a leaf, every triangle t whose own box is
//          within `limit` must pass the plane test: well shaped and
//          h_t = (p - x_t) . n_t >= target (x_t a vertex of t).
//      Nearer child first, the first leaf is the one a greedy descent from the root reaches,
//      unless a nearer child on the way is covered; a point that fails after passing one walks
//      again (from its lowered U), descending it for that leaf without plane tests: most points
//      pass without the leaf's distances, and that second walk clears more of the others.
//      If nothing failed, p is cleared: its hit becomes the witness (w, 1/3, 1/3), the centroid
//      of w, a triangle within U of p (the seed, the nearest of the first leaf, or one under
//      the box whose farthest point last lowered U: it is within `limit`, so it passes; the
//      test is repeated).
//      Otherwise p is searched exactly (dsBvhClosestList), from its witness, a triangle near
//      p, as the seed. The last frame's hits seed the next block.
//
// Why a cleared point is safe. For a triangle t under node n, any x in t lies in n's box, and
// h_t = n_t . (p - x) = a_n . (p - x) + (n_t - a_n) . (p - x) >= a_n . p - o_n - e_n |p - x|.
// Take x the point of t nearest p: for a t within `limit` of p, |p - x| is at most both the
// box's farthest point from p and `limit`, so h_t >= front_n(p): a node skipped for its cone
// holds only triangles with h_t >= target or farther than `limit` (the limit only shrinks; the
// second walk descends such a node only to measure distances, which lower U soundly). A node
// skipped for its box holds only triangles farther than `limit` (the limit only shrinks). So
// every triangle within the final `limit` of p has h_t >= target: it is well shaped and p lies at
// least clearance + m in front of its plane. The exact search's answer t* (distance D* <= U, or
// within the tie band of it) is one of them, so D* >= h_t* >= clearance + m (no triangle is nearer
// than its plane). The pseudo-normal at q* (face normal, edge normal or angle-weighted vertex
// normal) sums with non-negative weights the unit normals of triangles that contain q* (to within
// DS_FEATURE_TOL of an edge), all within `limit` of p, all passing; q* lies in each one's plane (to
// within the margin), so (p - q*) . n_s >= h_s - m > 0 for each, and the sign is positive. So the
// signed distance from the exact hit is +|p - q*| >= clearance: resolve() with an offset <=
// clearance leaves p where it is, and countInside() counts it outside. The witness gives the same
// verdicts: it passes the plane test (checked), its centroid is a face point, so
// |p - centroid| >= h_w >= clearance + m and (p - centroid) . n_w = h_w > 0. The cloth
// and every count are therefore bitwise those of the exact search, whatever the seeds, the
// chunking or the thread count (these only decide how many points are cleared). The argument
// needs no closed or non-self-intersecting driver: where limbs cross, or at an open border,
// triangles behind p come within `limit` and p is searched.
//
// Rounding. m = DS_CERT_MARGIN_* x S (S the scene scale of the tie band) is far above the
// rounding of every bound: the distances and boxes of the walk (a few ulps of S), the float
// (u, v) of exact hits (~1e-7 of an edge), the feature tolerance (1e-6 of an edge), the tie band
// (1e-7 S in double, 3e-5 S in float) and the normal of a well-shaped triangle (its direction is
// within a few ulps / sine of the truth; the cone spreads carry DS_CERT_CONE_SLACK_* for it and
// are rounded up when stored in float). The axes need not be exact: the bound holds for any a_n
// with e_n measured against a_n as stored.
//
// Cost. Per frame: one more refit pass (the cones). Per point: one triangle distance for U and
// those of the first leaf, then a walk that stops where the cones prove the surface behind the
// point, typically at nodes a few triangles across for cloth a triangle or two off the body,
// measuring no other distance: about as many node tests as the search's box tests, without its
// triangle distances (docs/performance.md has the figures). Points near the surface, inside,
// near crossings or slivers fail and pay the walk (twice where it passed a covered node before
// its first leaf) and the search.
//
// The recount. resolve() leaves every point cleared for it where it is, on the same poses, so
// its witness still answers a count (clearance 0 <= offset): the audit's recount after the
// resolution keeps those answers (closestOrClearBlock's `answered` and `keep`) and certifies or
// searches only the points the resolution moved.
//
// Not cleared, ever: every point of a backend with a binding mask (certifiable() is false:
// several trees, none over every triangle). Downstream, only resolve() and countInside() may
// read the hits of a cleared point: the wind's clearance, the binding switches and the transfer
// use closestBlock(), which always searches.

#include "certificate.h"

#include <cstddef>

namespace drivenshape::correction {

bool certifiable(const BvhTables& bvh, int triangleCount) {
  return bvh.classes.size() == 1 &&
         static_cast<int>(bvh.classes.front().triangles.size()) == triangleCount &&
         !bvh.nodes.empty() && !bvh.pointRoot.empty() && bvh.pointRoot.front() == 0;
}

std::vector<std::int32_t> nodeTriangles(const BvhTables& bvh) {
  std::vector<std::int32_t> out(bvh.nodes.size(), -1);
  // Children are deeper, so later in the array: fill from the end.
  for (std::size_t n = bvh.nodes.size(); n-- > 0;) {
    const DsBvhNode& node = bvh.nodes[n];
    out[n] = node.count > 0 ? bvh.leafTriangles[4 * static_cast<std::size_t>(node.first) + 3]
                            : out[static_cast<std::size_t>(node.left)];
  }
  return out;
}

}  // namespace drivenshape::correction
