// SPDX-License-Identifier: Apache-2.0
// Penetration resolution (contract: ClosestBackend::resolve in
// src/devices/closest.h; host reference: src/devices/host/host_resolve.cpp with
// src/database/surface_features.cpp, whose pseudoNormal() this file repeats in OpenCL C).
//
// Point p has its exact closest point q = a + u (b - a) + v (c - a) on triangle t. Its signed
// distance is s = |p - q|, negated when (p - q) . N < 0, with N the angle-weighted
// pseudo-normal at q (Baerentzen & Aanaes 2005): the face normal inside the triangle, the sum of
// the unit normals of the triangles on the edge, or the angle-weighted sum of the unit normals
// around the vertex (DS_FEATURE_TOL decides which). Each point keeps the side of the driver it
// lives on, sides[i] (+1 outside: cloth; -1 inside: a muscle under the skin; every point is
// outside when params.sided is 0). Where N is not zero, an outside point with s < offset moves
// to q + offset N / |N|, an inside point with s > -offset to q - offset N / |N|, and the frame's
// counter moves[f] is incremented; otherwise p stays.
//
// The exit fade (params.fade > 0; host reference: HostClosest::exitFraction): a point on the
// wrong side at depth d = |p - q| moves only the fraction a = clamp((d2 - d) / (fade d), 0, 1)
// of the way, with d2 its distance to the nearest other exit: the least distance to a triangle
// whose closest point lies farther than d from q, found by a walk of the BVH refitted to this
// block's poses (bvh.cl).
//
// Mapping: 1-D, local size DS_LOCAL_SIZE, one item per (frame f, point i), item id f * Vd + i.
// Requires the sources of closest.cl, transfer.cl (dsLoadPoint) and bvh.cl (dsBoxDistance2)
// before it.
//
//   poses            F x 3Vp float
//   triangles        T x 3 int
//   edgeStart        3T + 1 int    triangles on edge e of triangle t (e = 0 ab, 1 bc, 2 ca):
//   edgeTriangles                  edgeTriangles[edgeStart[3t + e] .. edgeStart[3t + e + 1] - 1]
//   vertexStart      Vp + 1 int    triangles around vertex v:
//   vertexTriangles                vertexTriangles[vertexStart[v] .. vertexStart[v + 1] - 1]
//   hits             F x Vd DsSurfaceHit   (triangle ids checked by the host)
//   points           F x 3Vd float, updated in place
//   moved            F int, incremented atomically (the host zeroes them)
//   sides            Vd char, +1 or -1 (read only when params.sided is 1), shared by every frame
//   nodes, leafTriangles, boxes, pointRoot   the BVH as bvh.cl reads it (dsResolve only; read
//                    only when params.fade > 0)

// Unit normal of triangle s; zero for a zero-area triangle.
inline ds_real3 dsFaceNormal(__global const float* pose, __global const int* triangles, int s) {
  const ds_real3 a = dsLoadPoint(pose, triangles[3 * s]);
  const ds_real3 n = cross(dsLoadPoint(pose, triangles[3 * s + 1]) - a,
                           dsLoadPoint(pose, triangles[3 * s + 2]) - a);
  const ds_real length = sqrt(dot(n, n));
  return length > 0 ? n / length : (ds_real3)(0, 0, 0);
}

// The signed distance of p from its hit on `pose` (see above); q receives the closest point and
// normal the pseudo-normal there (not unit length; zero where every triangle around is
// degenerate).
inline ds_real dsSignedDistance(__global const float* pose, __global const int* triangles,
                                __global const int* edgeStart, __global const int* edgeTriangles,
                                __global const int* vertexStart,
                                __global const int* vertexTriangles, const DsSurfaceHit hit,
                                const ds_real3 p, ds_real3* q, ds_real3* normal) {
  const int t = hit.triangle;
  const ds_real u = (ds_real)hit.u;
  const ds_real v = (ds_real)hit.v;
  const ds_real3 a = dsLoadPoint(pose, triangles[3 * t]);
  *q = a + u * (dsLoadPoint(pose, triangles[3 * t + 1]) - a) +
       v * (dsLoadPoint(pose, triangles[3 * t + 2]) - a);
  const ds_real3 offset = p - *q;

  const ds_real weight[3] = {1 - u - v, u, v};
  int zeros = 0;
  int nonZero = 0;
  int zero = 0;
  for (int k = 0; k < 3; ++k) {
    if (weight[k] <= (ds_real)DS_FEATURE_TOL) {
      ++zeros;
      zero = k;
    } else {
      nonZero = k;
    }
  }
  *normal = (ds_real3)(0, 0, 0);
  if (zeros >= 2) {
    const int vertex = triangles[3 * t + nonZero];
    for (int k = vertexStart[vertex]; k < vertexStart[vertex + 1]; ++k) {
      const int s = vertexTriangles[k];
      int at = 0;
      while (triangles[3 * s + at] != vertex) {
        ++at;
      }
      const ds_real3 corner = dsLoadPoint(pose, triangles[3 * s + at]);
      const ds_real3 e1 = dsLoadPoint(pose, triangles[3 * s + (at + 1) % 3]) - corner;
      const ds_real3 e2 = dsLoadPoint(pose, triangles[3 * s + (at + 2) % 3]) - corner;
      const ds_real lengths = sqrt(dot(e1, e1)) * sqrt(dot(e2, e2));
      if (lengths > 0) {
        const ds_real angle = acos(clamp(dot(e1, e2) / lengths, (ds_real)-1, (ds_real)1));
        *normal += angle * dsFaceNormal(pose, triangles, s);
      }
    }
  } else if (zeros == 1) {
    const int edge = 3 * t + (zero + 1) % 3;
    for (int k = edgeStart[edge]; k < edgeStart[edge + 1]; ++k) {
      *normal += dsFaceNormal(pose, triangles, edgeTriangles[k]);
    }
  } else {
    *normal = dsFaceNormal(pose, triangles, t);
  }

  const ds_real distance = sqrt(dot(offset, offset));
  const ds_real side = dot(offset, *normal);
  return side < 0 ? -distance : distance;
}

// The nearest way out (for points on their own side; ClosestBackend::setAlongNormal, host
// reference correction::nearestWayOut) of a point at `offset` = p - q from its closest point q,
// with signed distance s and unit pseudo-normal n there, for a skin offset `skin`: the unit
// vector of sign(s) (p - q) + max(DS_RESOLVE_STEADY skin - |s|, 0) n, or n where that vanishes.
inline ds_real3 dsNearestWayOut(const ds_real3 offset, const ds_real s, const ds_real3 n,
                                const float skin) {
  const ds_real steady = (ds_real)DS_RESOLVE_STEADY * (ds_real)skin - fabs(s);
  const ds_real3 way = (s < 0 ? -offset : offset) + fmax(steady, (ds_real)0) * n;
  const ds_real length = sqrt(dot(way, way));
  return length > 0 ? way / length : n;
}

// The nearest other exit of p (see above): the least distance from p to a triangle of the tree
// at `root` whose closest point lies farther than `depth` from q; INFINITY when there is none.
inline ds_real dsOtherExit(ds_real3 p, ds_real3 q, ds_real depth, __global const float* pose,
                           __global const DsBvhNode* nodes, __global const int4* leafTriangles,
                           __global const float* frameBoxes, int root) {
  ds_real best = INFINITY;  // squared
  const ds_real reach = depth * depth;
  int stack[DS_BVH_MAX_DEPTH];
  ds_real stackDistance[DS_BVH_MAX_DEPTH];
  int sp = 0;
  int node = root;
  while (node >= 0) {
    const DsBvhNode current = nodes[node];
    int next = -1;
    if (current.count > 0) {
      for (int k = current.first; k < current.first + current.count; ++k) {
        const int4 tri = leafTriangles[k];
        const ds_real3 a = dsLoad3(pose, tri.x);
        const ds_real3 b = dsLoad3(pose, tri.y);
        const ds_real3 c = dsLoad3(pose, tri.z);
        ds_real u;
        ds_real v;
        const ds_real d2 = dsTriangleDistance2(p, a, b, c, &u, &v);
        if (d2 < best) {
          const ds_real3 e = a + u * (b - a) + v * (c - a) - q;
          if (dot(e, e) > reach) {
            best = d2;
          }
        }
      }
    } else {
      const ds_real dl = dsBoxDistance2(p, frameBoxes + (size_t)current.left * 6);
      const ds_real dr = dsBoxDistance2(p, frameBoxes + (size_t)current.right * 6);
      const int leftFirst = dl <= dr;
      const ds_real dNear = leftFirst ? dl : dr;
      const ds_real dFar = leftFirst ? dr : dl;
      if (dNear < best) {
        next = leftFirst ? current.left : current.right;
        if (dFar < best) {
          stack[sp] = leftFirst ? current.right : current.left;
          stackDistance[sp] = dFar;
          ++sp;
        }
      }
    }
    while (next < 0 && sp > 0) {
      --sp;
      if (stackDistance[sp] < best) {
        next = stack[sp];
      }
    }
    node = next;
  }
  return sqrt(best);
}

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsResolve(
    __global const float* poses, __global const int* triangles, __global const int* edgeStart,
    __global const int* edgeTriangles, __global const int* vertexStart,
    __global const int* vertexTriangles, __global const DsSurfaceHit* hits, __global float* points,
    __global int* moved, __global const char* sides, const DsResolveParams params,
    __global const DsBvhNode* nodes, __global const int4* leafTriangles,
    __global const float* boxes, __global const int* pointRoot) {
  const int item = (int)get_global_id(0);
  if (item >= params.frameCount * params.pointCount) {
    return;
  }
  const int frame = item / params.pointCount;
  __global const float* pose = poses + (size_t)frame * (size_t)(3 * params.vertexCount);
  ds_real3 q;
  ds_real3 normal;
  const ds_real3 p = dsLoadPoint(points, item);
  const ds_real signedDistance =
      dsSignedDistance(pose, triangles, edgeStart, edgeTriangles, vertexStart, vertexTriangles,
                       hits[item], p, &q, &normal);
  const ds_real length = sqrt(dot(normal, normal));
  // Inside points mirror outside ones: the offset surface under the skin is at -offset.
  const int point = item - frame * params.pointCount;
  const bool inside = params.sided != 0 && sides[point] < 0;
  const ds_real target = inside ? -(ds_real)params.offset : (ds_real)params.offset;
  if (length > 0 && (inside ? signedDistance > target : signedDistance < target)) {
    const bool wrongSide = inside ? signedDistance > 0 : signedDistance < 0;
    const ds_real3 full =
        q + (params.alongNormal != 0 || wrongSide
                 ? (target / length) * normal
                 : target * dsNearestWayOut(p - q, signedDistance, normal / length, params.offset));
    ds_real fraction = 1;
    const ds_real depth = fabs(signedDistance);
    if (params.fade > 0 && depth > 0 && wrongSide) {
      const ds_real other =
          dsOtherExit(p, q, depth, pose, nodes, leafTriangles,
                      boxes + (size_t)frame * (size_t)params.nodeCount * 6, pointRoot[point]);
      fraction = clamp((other - depth) / ((ds_real)params.fade * depth), (ds_real)0, (ds_real)1);
    }
    if (fraction <= 0) {
      return;
    }
    const ds_real3 result = fraction < 1 ? p + fraction * (full - p) : full;
    points[3 * item] = (float)result.x;
    points[3 * item + 1] = (float)result.y;
    points[3 * item + 2] = (float)result.z;
    atomic_inc(&moved[frame]);
  }
}

// The strain limit's skin planes (contract: ClosestBackend::skinPlanes; host reference:
// HostClosest::skinPlanes in src/devices/host/host_resolve.cpp). Point i of frame f gets the
// plane (m, c), m unit, that the strain limit keeps it in front of (m . x >= c): on its own side
// of the skin, m is the way dsResolve would move it (the pseudo-normal, or the nearest way out)
// and c = m . q + offset; on the wrong side at depth d, m is the unit pseudo-normal and
// c = m . q + offset - D (1 - w) / w with D = params.depth and w = clamp((1.5 D - d) / (0.5 D),
// 0, 1): the offset up to D deep, then sinking away continuously until no plane at 1.5 D. Every
// other point gets (0, 0, 0, 0): a point that lives inside, one the clearance certificate
// answered without a search (answered[item] != 0, read when params.answered is 1), one at signed
// distance params.reach or more, one 1.5 D deep or deeper, or one whose pseudo-normal vanishes.
// Same mapping and first arguments as dsResolve, with `points` read only.
//
//   answered   F x Vd int (any buffer when params.answered is 0)
//   planes     F x Vd float4, written
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsSkinPlanes(
    __global const float* poses, __global const int* triangles, __global const int* edgeStart,
    __global const int* edgeTriangles, __global const int* vertexStart,
    __global const int* vertexTriangles, __global const DsSurfaceHit* hits,
    __global const float* points, __global const int* answered, __global const char* sides,
    __global float4* planes, const DsResolveParams params) {
  const int item = (int)get_global_id(0);
  if (item >= params.frameCount * params.pointCount) {
    return;
  }
  const int frame = item / params.pointCount;
  const int point = item - frame * params.pointCount;
  float4 plane = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  const bool searched = params.answered == 0 || answered[item] == 0;
  const bool insidePoint = params.sided != 0 && sides[point] < 0;
  if (searched && !insidePoint) {
    __global const float* pose = poses + (size_t)frame * (size_t)(3 * params.vertexCount);
    ds_real3 q;
    ds_real3 normal;
    const ds_real3 p = dsLoadPoint(points, item);
    const ds_real s = dsSignedDistance(pose, triangles, edgeStart, edgeTriangles, vertexStart,
                                       vertexTriangles, hits[item], p, &q, &normal);
    const ds_real length = sqrt(dot(normal, normal));
    const ds_real depth = (ds_real)params.depth;
    if (length > 0 && s > -(ds_real)1.5 * depth && s < (ds_real)params.reach) {
      const ds_real3 n = normal / length;
      const ds_real3 m =
          s < 0 || params.alongNormal != 0 ? n : dsNearestWayOut(p - q, s, n, params.offset);
      const ds_real w = s < -depth ? (1.5 * depth + s) / (0.5 * depth) : 1;
      plane = (float4)((float)m.x, (float)m.y, (float)m.z,
                       (float)(dot(m, q) + params.offset - depth * (1 - w) / w));
    }
  }
  planes[item] = plane;
}

// Wrong-side counts (contract: ClosestBackend::countInside; host reference: InsideAudit in
// src/pipeline/inside_audit.cpp): inside[f] counts the points of frame f on the wrong side
// of the skin: whose signed distance, rounded to float as the host rounds it, is negative for
// an outside point (cloth inside the body) or positive for an inside point (a muscle through
// the skin). Same mapping and arguments as dsResolve, with `points` read only and `inside` in
// place of `moved`.
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsCountInside(
    __global const float* poses, __global const int* triangles, __global const int* edgeStart,
    __global const int* edgeTriangles, __global const int* vertexStart,
    __global const int* vertexTriangles, __global const DsSurfaceHit* hits,
    __global const float* points, __global int* inside, __global const char* sides,
    const DsResolveParams params) {
  const int item = (int)get_global_id(0);
  if (item >= params.frameCount * params.pointCount) {
    return;
  }
  const int frame = item / params.pointCount;
  __global const float* pose = poses + (size_t)frame * (size_t)(3 * params.vertexCount);
  ds_real3 q;
  ds_real3 normal;
  const ds_real signedDistance =
      dsSignedDistance(pose, triangles, edgeStart, edgeTriangles, vertexStart, vertexTriangles,
                       hits[item], dsLoadPoint(points, item), &q, &normal);
  const bool insidePoint = params.sided != 0 && sides[item - frame * params.pointCount] < 0;
  if (insidePoint ? (float)signedDistance > 0.0f : (float)signedDistance < 0.0f) {
    atomic_inc(&inside[frame]);
  }
}
