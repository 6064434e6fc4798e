// SPDX-License-Identifier: Apache-2.0
// The clearance certificate (contract: ClosestBackend::closestOrClearBlock in
// src/devices/closest.h; host reference: src/devices/host/host_certificate.cpp;
// the scheme and why a cleared point is safe: src/devices/certificate.cpp). Requires
// closest.cl (dsLoad3, dsCandidateDistance2) and bvh.cl (DS_BVH_MAX_DEPTH) before it.
//
//   poses          F x 3Vp float        vertex v of frame f at [f * 3Vp + 3v]
//   nodes          N DsBvhNode          the tree over every triangle (one search class)
//   leafTriangles  L int4               (vertex a, vertex b, vertex c, triangle id) per slot
//   boxes          F x N x 6 float      node n of frame f at [(f * N + n) * 6] (dsBvhRefit)
//   cones          F x N DsCertCone     node n of frame f at [f * N + n] (dsCertRefitCones)

// Whether triangle (a, b, c) is well shaped (DS_CERT_SIN2) and, if so, its unit normal.
inline int dsCertNormal(ds_real3 a, ds_real3 b, ds_real3 c, ds_real3* normal) {
  const ds_real3 ab = b - a;
  const ds_real3 ac = c - a;
  const ds_real3 n = cross(ab, ac);
  const ds_real nn = dot(n, n);
  if (!(nn > (ds_real)DS_CERT_SIN2 * dot(ab, ab) * dot(ac, ac))) {
    return 0;
  }
  *normal = n / sqrt(nn);
  return 1;
}

// The plane test of p against triangle (a, b, c): well shaped, and p at least `target` in
// front of its plane along the unit normal.
inline int dsCertInFront(ds_real3 p, ds_real3 a, ds_real3 b, ds_real3 c, ds_real target) {
  const ds_real3 ab = b - a;
  const ds_real3 ac = c - a;
  const ds_real3 n = cross(ab, ac);
  const ds_real nn = dot(n, n);
  const ds_real h = dot(p - a, n);
  return nn > (ds_real)DS_CERT_SIN2 * dot(ab, ab) * dot(ac, ac) && h > 0 &&
         h * h >= target * target * nn;
}

inline float dsRoundUp(ds_real x) {
  float rounded = (float)x;
  if ((ds_real)rounded < x) {
    rounded = nextafter(rounded, (float)INFINITY);
  }
  return isfinite(x) ? rounded : (float)INFINITY;
}

// dsCertRefitCones: one item per (frame, node of one depth), 1-D, local size DS_LOCAL_SIZE,
// deepest depth first, after dsBvhRefit. A leaf's axis is the normalised sum of its triangles'
// unit normals, its spread the largest distance of one of them from the axis as stored (float)
// plus DS_CERT_CONE_SLACK, its offset the largest axis . x over its vertices; an inner node's
// axis is the normalised sum of its children's, its spread the larger of |child axis - axis| +
// child spread (the triangle inequality), its offset the larger of child offset + the largest
// (axis - child axis) . x over the child's box. Spreads and offsets are rounded up; a spread of
// INFINITY marks a node without a useful cone.
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsCertRefitCones(
    __global const float* poses, __global const DsBvhNode* nodes,
    __global const int4* leafTriangles, __global const float* boxes, __global DsCertCone* cones,
    const DsCertParams params) {
  const int id = (int)get_global_id(0);
  if (id >= params.frameCount * params.levelCount) {
    return;
  }
  const int frame = id / params.levelCount;
  const int n = params.levelFirst + (id - frame * params.levelCount);
  __global const float* pose = poses + (size_t)frame * (size_t)(3 * params.vertexCount);
  __global DsCertCone* frameCones = cones + (size_t)frame * (size_t)params.nodeCount;
  __global const float* frameBoxes = boxes + (size_t)frame * (size_t)params.nodeCount * 6;
  const DsBvhNode node = nodes[n];
  DsCertCone cone;
  cone.spread = INFINITY;
  cone.axis[0] = 0.0f;
  cone.axis[1] = 0.0f;
  cone.axis[2] = 0.0f;
  cone.offset = INFINITY;
  cone.pad0 = 0.0f;
  cone.pad1 = 0.0f;
  cone.pad2 = 0.0f;
  ds_real3 sum = (ds_real3)(0, 0, 0);
  int usable = 1;
  if (node.count > 0) {
    for (int k = node.first; k < node.first + node.count && usable; ++k) {
      const int4 tri = leafTriangles[k];
      ds_real3 normal;
      usable =
          dsCertNormal(dsLoad3(pose, tri.x), dsLoad3(pose, tri.y), dsLoad3(pose, tri.z), &normal);
      sum += usable ? normal : (ds_real3)(0, 0, 0);
    }
  } else {
    const DsCertCone left = frameCones[node.left];
    const DsCertCone right = frameCones[node.right];
    usable = isfinite(left.spread) && isfinite(right.spread);
    sum = (ds_real3)((ds_real)left.axis[0] + (ds_real)right.axis[0],
                     (ds_real)left.axis[1] + (ds_real)right.axis[1],
                     (ds_real)left.axis[2] + (ds_real)right.axis[2]);
  }
  const ds_real norm = sqrt(dot(sum, sum));
  if (usable && norm > 0) {
    const ds_real3 unit = sum / norm;
    cone.axis[0] = (float)unit.x;
    cone.axis[1] = (float)unit.y;
    cone.axis[2] = (float)unit.z;
    const ds_real3 axis =
        (ds_real3)((ds_real)cone.axis[0], (ds_real)cone.axis[1], (ds_real)cone.axis[2]);
    ds_real spread = 0;
    ds_real offset = -INFINITY;
    if (node.count > 0) {
      for (int k = node.first; k < node.first + node.count; ++k) {
        const int4 tri = leafTriangles[k];
        const ds_real3 a = dsLoad3(pose, tri.x);
        const ds_real3 b = dsLoad3(pose, tri.y);
        const ds_real3 c = dsLoad3(pose, tri.z);
        ds_real3 normal;
        dsCertNormal(a, b, c, &normal);
        spread = fmax(spread, length(normal - axis));
        offset = fmax(offset, fmax(dot(axis, a), fmax(dot(axis, b), dot(axis, c))));
      }
      spread += (ds_real)DS_CERT_CONE_SLACK;
    } else {
      // Under child c: axis . x = child axis . x + (axis - child axis) . x, the second term at
      // most its maximum over the child's box.
      for (int side = 0; side < 2; ++side) {
        const int c = side == 0 ? node.left : node.right;
        const DsCertCone child = frameCones[c];
        const ds_real3 childAxis =
            (ds_real3)((ds_real)child.axis[0], (ds_real)child.axis[1], (ds_real)child.axis[2]);
        spread = fmax(spread, length(childAxis - axis) + (ds_real)child.spread);
        __global const float* box = frameBoxes + (size_t)c * 6;
        const ds_real3 turn = axis - childAxis;
        const ds_real3 support =
            fmax(turn * (ds_real3)((ds_real)box[0], (ds_real)box[1], (ds_real)box[2]),
                 turn * (ds_real3)((ds_real)box[3], (ds_real)box[4], (ds_real)box[5]));
        offset = fmax(offset, (ds_real)child.offset + support.x + support.y + support.z);
      }
    }
    cone.offset = dsRoundUp(offset);
    // A cone as wide as the sphere proves nothing.
    cone.spread = spread < 2 ? dsRoundUp(spread) : INFINITY;
  }
  frameCones[n] = cone;
}

// One node of the walk for p (its box and cone on the frame): whether it must be opened, i.e.
// its box is within `limit` and its cone does not prove p at least `target` in front of every
// triangle under it, n_t . (p - x) >= axis . p - offset - spread * (the box's farthest point from
// p). *distance receives the box's squared distance. A box within `limit` also lowers the upper
// bound U (core2 = U^2, limit = U + margin) to its farthest point from p, which bounds the
// distance to any triangle in it, and then its `triangle` (one under it) becomes the witness,
// a triangle within U of p.
inline int dsCertOpen(ds_real3 p, __global const float* box, const DsCertCone cone, int triangle,
                      ds_real target, ds_real margin, ds_real* limit, ds_real* core2, int* witness,
                      ds_real* distance) {
  const ds_real3 low = (ds_real3)((ds_real)box[0], (ds_real)box[1], (ds_real)box[2]);
  const ds_real3 high = (ds_real3)((ds_real)box[3], (ds_real)box[4], (ds_real)box[5]);
  const ds_real3 e = fmax(fmax(low - p, p - high), (ds_real3)(0, 0, 0));
  *distance = dot(e, e);
  if (*distance > *limit * *limit) {
    return 0;
  }
  const ds_real3 farthest = fmax(fabs(p - low), fabs(p - high));
  const ds_real far2 = dot(farthest, farthest);
  if (far2 < *core2) {
    *core2 = far2;
    *limit = sqrt(far2) + margin;
    *witness = triangle;
  }
  // Covered when front >= spread * min(far, limit), compared squared: only the triangles within
  // the limit must pass, and such a triangle's nearest point x has |p - x| <= both.
  const ds_real front = (ds_real)cone.axis[0] * p.x + (ds_real)cone.axis[1] * p.y +
                        (ds_real)cone.axis[2] * p.z - (ds_real)cone.offset - target;
  const ds_real spread = (ds_real)cone.spread;
  const ds_real reach2 = fmin(far2, *limit * *limit);
  return !(isfinite(spread) && front >= 0 && front * front >= spread * spread * reach2);
}

// The walk of dsCertCheck from the root for p: 0 as soon as a triangle within `limit` does not
// have p the target in front of it, else 1. U (core2 = U^2, limit = U + reachMargin) and the
// witness come in from the seed and fall on the way: with the boxes opened (dsCertOpen) and with
// the triangles' distances of the first leaf reached, before anything is plane-tested. The walk
// goes nearer child first, so that leaf is the one a greedy descent from the root would reach,
// unless the nearer child is covered by its cone: then, with `measureCovered`, the walk still
// descends it (nearer child only, nothing to plane-test) for that leaf and goes on from the
// stack; without, it goes on and sets *skipped.
inline int dsCertWalk(ds_real3 p, __global const float* pose, __global const DsBvhNode* nodes,
                      __global const int4* leafTriangles, __global const int* nodeTriangle,
                      __global const float* frameBoxes, __global const DsCertCone* frameCones,
                      ds_real target, ds_real reachMargin, int measureCovered, ds_real* limit,
                      ds_real* core2, int* witness, int* skipped) {
  ds_real u;
  ds_real v;
  ds_real distance;
  int pass = 1;
  int node = dsCertOpen(p, frameBoxes, frameCones[0], nodeTriangle[0], target, reachMargin, limit,
                        core2, witness, &distance)
                 ? 0
                 : -1;
  // One push per level, and one more where the walk descends a covered node to measure it.
  int stack[DS_BVH_MAX_DEPTH + 2];
  ds_real stackDistance[DS_BVH_MAX_DEPTH + 2];
  int sp = 0;
  int measure = 1;
  int covered = 0;
  while (node >= 0 && pass) {
    const DsBvhNode current = nodes[node];
    int next = -1;
    if (current.count > 0) {
      for (int k = current.first; k < current.first + current.count && measure; ++k) {
        const int4 tri = leafTriangles[k];
        const ds_real d2 = dsTriangleDistance2(p, dsLoad3(pose, tri.x), dsLoad3(pose, tri.y),
                                               dsLoad3(pose, tri.z), &u, &v);
        if (d2 < *core2) {
          *core2 = d2;
          *witness = tri.w;
          *limit = fmin(*limit, sqrt(d2) + reachMargin);
        }
      }
      measure = 0;
      for (int k = current.first; k < current.first + current.count && pass && !covered; ++k) {
        const int4 tri = leafTriangles[k];
        const ds_real3 a = dsLoad3(pose, tri.x);
        const ds_real3 b = dsLoad3(pose, tri.y);
        const ds_real3 c = dsLoad3(pose, tri.z);
        const ds_real3 e =
            fmax(fmax(fmin(a, fmin(b, c)) - p, p - fmax(a, fmax(b, c))), (ds_real3)(0, 0, 0));
        const ds_real d2 = dot(e, e);
        if (d2 > *limit * *limit) {
          continue;
        }
        pass = dsCertInFront(p, a, b, c, target);
      }
      covered = 0;
    } else {
      // Both children (the limit may shrink on the way), then the open ones within the final
      // limit, the nearer first.
      const int child[2] = {current.left, current.right};
      ds_real distances[2];
      int open[2];
      for (int side = 0; side < 2; ++side) {
        open[side] = dsCertOpen(p, frameBoxes + (size_t)child[side] * 6, frameCones[child[side]],
                                nodeTriangle[child[side]], target, reachMargin, limit, core2,
                                witness, &distances[side]);
      }
      const int nearSide = distances[0] <= distances[1] ? 0 : 1;
      const ds_real limit2 = *limit * *limit;
      if (covered) {
        next = child[nearSide];
      } else {
        if (open[nearSide] && distances[nearSide] <= limit2) {
          next = child[nearSide];
        }
        if (open[1 - nearSide] && distances[1 - nearSide] <= limit2) {
          if (next < 0) {
            next = child[1 - nearSide];
          } else {
            stack[sp] = child[1 - nearSide];
            stackDistance[sp] = distances[1 - nearSide];
            ++sp;
          }
        }
        if (measure && !open[nearSide] && distances[nearSide] <= limit2) {
          *skipped = 1;
          if (measureCovered) {
            if (next >= 0) {
              stack[sp] = next;
              stackDistance[sp] = distances[next == child[0] ? 0 : 1];
              ++sp;
            }
            next = child[nearSide];
            covered = 1;
          }
        }
      }
    }
    while (next < 0 && sp > 0) {
      --sp;
      if (stackDistance[sp] <= *limit * *limit) {
        next = stack[sp];
      }
    }
    node = next;
  }
  return pass;
}

// dsCertCheck: one item per (frame f, point i), item id f * Vd + i, 1-D, local size
// DS_LOCAL_SIZE. The walk of src/devices/certificate.cpp: `limit` starts at the distance from p
// to its seed triangle plus the margin and twice params.reach (the answer holds within reach of
// p), and shrinks to the farthest point of any box seen (an upper bound too) and to the nearest
// triangle of the first leaf reached (measured before its plane tests); nodes farther than
// `limit` are skipped, nodes whose cone covers them too, the others opened nearer child first; a
// leaf's triangles within `limit` must pass the plane test one by one. If all do (and the
// witness w, a triangle within U of p, passes it too), the point is cleared: its hit becomes (w,
// 1/3, 1/3) and its answered mark 1 (dsCertCount counts them); otherwise it is appended to
// `search` (its item id; `searchCount` counts them, the host zeroes it).
//
//   triangles      T x 3 int
//   nodeTriangle   N int                a triangle under each node (certificate.h)
//   points         F x 3Vd float
//   seeds          Vd DsSurfaceHit      .triangle: the previous block's last hits (bvh.cl)
//   hits           F x Vd DsSurfaceHit  with params.keep read first: each item's answer of the
//                                       call before, its seed; written: a cleared item's
//                                       witness, and an item to search's witness triangle (the
//                                       search's seed, dsBvhClosestList)
//   answered       F x Vd int           1 for an item cleared (or kept), 0 for one to search;
//                                       read first with params.keep
//   search         F x Vd int           appended atomically (order unspecified)
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsCertCheck(
    __global const float* poses, __global const int* triangles, __global const DsBvhNode* nodes,
    __global const int4* leafTriangles, __global const int* nodeTriangle,
    __global const float* boxes, __global const DsCertCone* cones, __global const float* points,
    __global const DsSurfaceHit* seeds, __global DsSurfaceHit* hits, __global int* answered,
    __global int* search, __global int* searchCount, const DsCertParams params) {
  const int item = (int)get_global_id(0);
  if (item >= params.frameCount * params.pointCount) {
    return;
  }
  const int frame = item / params.pointCount;
  const int point = item - frame * params.pointCount;
  if (params.keep && answered[item] != 0) {
    return;
  }
  __global const float* pose = poses + (size_t)frame * (size_t)(3 * params.vertexCount);
  __global const float* frameBoxes = boxes + (size_t)frame * (size_t)params.nodeCount * 6;
  __global const DsCertCone* frameCones = cones + (size_t)frame * (size_t)params.nodeCount;
  const ds_real3 p = dsLoad3(points, item);
  const ds_real margin = (ds_real)params.margin;
  const ds_real target = (ds_real)params.clearance + margin;
  // Triangles within U + 2 reach of p can be the closest of a point within reach of p.
  const ds_real reachMargin = margin + 2 * (ds_real)params.reach;
  // The upper bound U starts at the distance to the seed triangle, the first witness: with
  // params.keep the item's own answer before it moved (close), else the point's hit on the
  // previous block's last frame. The walk turns aside into covered nodes for the first leaf's
  // distances only when it failed without: most points pass without those distances, and the
  // others pass more often with them.
  int witness = params.keep ? hits[item].triangle : seeds[point].triangle;
  ds_real u;
  ds_real v;
  ds_real core2 = dsCandidateDistance2(p, pose, triangles, witness, &u, &v);
  ds_real limit = sqrt(core2) + reachMargin;
  int skipped = 0;
  int pass = dsCertWalk(p, pose, nodes, leafTriangles, nodeTriangle, frameBoxes, frameCones, target,
                        reachMargin, 0, &limit, &core2, &witness, &skipped);
  if (!pass && skipped) {
    pass = dsCertWalk(p, pose, nodes, leafTriangles, nodeTriangle, frameBoxes, frameCones, target,
                      reachMargin, 1, &limit, &core2, &witness, &skipped);
  }
  pass = pass && dsCertInFront(p, dsLoad3(pose, triangles[3 * witness]),
                               dsLoad3(pose, triangles[3 * witness + 1]),
                               dsLoad3(pose, triangles[3 * witness + 2]), target);
  answered[item] = pass;
  if (!pass) {
    hits[item].triangle = witness;
    search[atomic_inc(searchCount)] = item;
    return;
  }
  DsSurfaceHit hit;
  hit.triangle = witness;
  hit.u = DS_CERT_THIRD;
  hit.v = DS_CERT_THIRD;
  const ds_real3 a = dsLoad3(pose, triangles[3 * witness]);
  const ds_real3 centroid = a + (ds_real)hit.u * (dsLoad3(pose, triangles[3 * witness + 1]) - a) +
                            (ds_real)hit.v * (dsLoad3(pose, triangles[3 * witness + 2]) - a);
  const ds_real3 offset = p - centroid;
  hit.distance2 = (float)dot(offset, offset);
  hits[item] = hit;
}

// dsCertCount: cleared[f] = how many of frame f's items dsCertCheck answered (answered[f * Vd +
// i] != 0), after it. One work-group per frame: 2-D range (DS_LOCAL_SIZE, F), local size
// (DS_LOCAL_SIZE, 1). (dsCertCheck counted them itself with an atomic increment per answered
// item, every item of a frame on one counter: 2-4% of its time on PoCL's two cores, and a
// counter that every thread of a GPU's frame would queue on.)
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsCertCount(
    __global const int* answered, __global int* cleared, const int pointCount) {
  __local int partial[DS_LOCAL_SIZE];
  const int lane = (int)get_local_id(0);
  const int frame = (int)get_global_id(1);
  __global const int* marks = answered + (size_t)frame * (size_t)pointCount;
  int sum = 0;
  for (int i = lane; i < pointCount; i += DS_LOCAL_SIZE) {
    sum += marks[i] != 0 ? 1 : 0;
  }
  partial[lane] = sum;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int width = DS_LOCAL_SIZE / 2; width > 0; width /= 2) {
    if (lane < width) {
      partial[lane] += partial[lane + width];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (lane == 0) {
    cleared[frame] = partial[0];
  }
}
