// SPDX-License-Identifier: Apache-2.0
// Exact closest triangle by a walk of refitted bounding-volume hierarchies (contract:
// ClosestBackend::closest in src/devices/closest.h; host reference:
// src/devices/host/host_closest.cpp; the scheme and its exactness argument:
// src/database/bvh.cpp). Requires closest.cl before it (dsLoad3, dsTriangleDistance2,
// dsCandidateDistance2).
//
//   poses          F x 3Vp float    vertex v of frame f at [f * 3Vp + 3v]
//   nodes          N DsBvhNode      all trees, sorted by depth
//   leafTriangles  L int4           (vertex a, vertex b, vertex c, triangle id) per leaf slot
//   boxes          F x N x 6 float  node n of frame f: min xyz, max xyz at [(f * N + n) * 6]

// dsBvhRefit: one item per (frame, node of one depth), 1-D, local size DS_LOCAL_SIZE. Leaves
// take the min/max of their triangles' vertices, inner nodes the union of their children
// (refitted by the launch for the next depth, which ran before this one).
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsBvhRefit(
    __global const float* poses, __global const DsBvhNode* nodes,
    __global const int4* leafTriangles, __global float* boxes, const DsBvhRefitParams params) {
  const int id = (int)get_global_id(0);
  if (id >= params.frameCount * params.levelCount) {
    return;
  }
  const int frame = id / params.levelCount;
  const int n = params.levelFirst + (id - frame * params.levelCount);
  __global const float* pose = poses + (size_t)frame * (size_t)(3 * params.vertexCount);
  __global float* frameBoxes = boxes + (size_t)frame * (size_t)params.nodeCount * 6;
  const DsBvhNode node = nodes[n];
  float3 low;
  float3 high;
  if (node.count > 0) {
    low = (float3)(INFINITY, INFINITY, INFINITY);
    high = -low;
    for (int k = node.first; k < node.first + node.count; ++k) {
      const int4 tri = leafTriangles[k];
      const float3 a = vload3(tri.x, pose);
      const float3 b = vload3(tri.y, pose);
      const float3 c = vload3(tri.z, pose);
      low = fmin(low, fmin(a, fmin(b, c)));
      high = fmax(high, fmax(a, fmax(b, c)));
    }
  } else {
    __global const float* left = frameBoxes + (size_t)node.left * 6;
    __global const float* right = frameBoxes + (size_t)node.right * 6;
    low = fmin(vload3(0, left), vload3(0, right));
    high = fmax(vload3(1, left), vload3(1, right));
  }
  vstore3(low, 0, frameBoxes + (size_t)n * 6);
  vstore3(high, 1, frameBoxes + (size_t)n * 6);
}

// Squared distance from p to an axis-aligned box (zero inside).
inline ds_real dsBoxDistance2(ds_real3 p, __global const float* box) {
  const ds_real3 low = (ds_real3)((ds_real)box[0], (ds_real)box[1], (ds_real)box[2]);
  const ds_real3 high = (ds_real3)((ds_real)box[3], (ds_real)box[4], (ds_real)box[5]);
  const ds_real3 e = fmax(fmax(low - p, p - high), (ds_real3)(0, 0, 0));
  return dot(e, e);
}

// dsBvhClosest: one item per (frame f, point i), item id f * Vd + i, 1-D, local size
// DS_LOCAL_SIZE.
//
//   triangles  T x 3 int         vertex ids (for the seeds)
//   points     F x 3Vd float
//   pointRoot  Vd int            root node of point i's tree (its mask class)
//   seeds      Vd DsSurfaceHit   .triangle: a triangle of point i's class (the first upper bound;
//                                the previous block's last hits, copied on the device)
//   hits       F x Vd DsSurfaceHit
//
// dsBvhClosestList: the same search for the items listed in search[0 .. searchCount - 1] (item
// ids f * Vd + i, any order; one work item per entry): the points the clearance certificate
// (certificate.cl) could not clear, each seeded with the triangle it left in hits[item], its
// walk's witness (the answer does not depend on the seed: src/database/bvh.cpp).

// The search of item `item` (frame f, point i); the kernels below write its answer.
inline DsSurfaceHit dsBvhSearch(int item, __global const float* poses,
                                __global const int* triangles, __global const DsBvhNode* nodes,
                                __global const int4* leafTriangles, __global const float* boxes,
                                __global const float* points, __global const int* pointRoot,
                                const int seed, const DsBvhQueryParams params) {
  const int frame = item / params.pointCount;
  const int point = item - frame * params.pointCount;
  __global const float* pose = poses + (size_t)frame * (size_t)(3 * params.vertexCount);
  __global const float* frameBoxes = boxes + (size_t)frame * (size_t)params.nodeCount * 6;
  const ds_real3 p = dsLoad3(points, item);
  const int root = pointRoot[point];
  const ds_real tieRelative = (ds_real)params.tieRelative;
  const ds_real tieAbsolute = (ds_real)params.tieAbsolute;
  const ds_real pruneScale = 1 + (ds_real)params.pruneRelative;
  const ds_real pruneAbsolute = (ds_real)params.pruneAbsolute;

  ds_real u;
  ds_real v;
  int bestTriangle = seed;
  ds_real best = dsCandidateDistance2(p, pose, triangles, seed, &u, &v);
  ds_real band = best + tieRelative * best + tieAbsolute;

  // The triangles within the tie band of the best so far (every triangle within the final
  // band is visited by pass 1, see bvh.cpp); when more than DS_BVH_TIES of them are seen at
  // once, pass 2 finds the tie-break instead.
  int tieTriangle[DS_BVH_TIES];
  ds_real tieDistance[DS_BVH_TIES];
  float tieU[DS_BVH_TIES];
  float tieV[DS_BVH_TIES];
  int ties = 1;
  int overflow = 0;
  tieTriangle[0] = seed;
  tieDistance[0] = best;
  tieU[0] = (float)u;
  tieV[0] = (float)v;

  int stack[DS_BVH_MAX_DEPTH];
  ds_real stackDistance[DS_BVH_MAX_DEPTH];

  // Pass 1: the smallest distance. Nearest child first; a box is opened only while it may hold
  // a triangle within the tie band of the best so far (with the pruning margin).
  int sp = 0;
  int node = root;
  while (node >= 0) {
    const DsBvhNode current = nodes[node];
    int next = -1;
    if (current.count > 0) {
      for (int k = current.first; k < current.first + current.count; ++k) {
        const int4 tri = leafTriangles[k];
        if (tri.w == seed) {
          continue;
        }
        const ds_real3 a = dsLoad3(pose, tri.x);
        const ds_real3 b = dsLoad3(pose, tri.y);
        const ds_real3 c = dsLoad3(pose, tri.z);
        // The triangle's own box first: a cheap lower bound of its distance (as for the nodes).
        const ds_real3 e =
            fmax(fmax(fmin(a, fmin(b, c)) - p, p - fmax(a, fmax(b, c))), (ds_real3)(0, 0, 0));
        if (dot(e, e) > band * pruneScale + pruneAbsolute) {
          continue;
        }
        const ds_real d2 = dsTriangleDistance2(p, a, b, c, &u, &v);
        if (d2 > band) {
          continue;
        }
        if (d2 < best) {
          best = d2;
          bestTriangle = tri.w;
          band = best + tieRelative * best + tieAbsolute;
          int kept = 0;
          for (int j = 0; j < ties; ++j) {
            if (tieDistance[j] <= band) {
              tieTriangle[kept] = tieTriangle[j];
              tieDistance[kept] = tieDistance[j];
              tieU[kept] = tieU[j];
              tieV[kept] = tieV[j];
              ++kept;
            }
          }
          ties = kept;
        }
        if (ties < DS_BVH_TIES) {
          tieTriangle[ties] = tri.w;
          tieDistance[ties] = d2;
          tieU[ties] = (float)u;
          tieV[ties] = (float)v;
          ++ties;
        } else {
          overflow = 1;
        }
      }
    } else {
      const ds_real limit = band * pruneScale + pruneAbsolute;
      const ds_real dl = dsBoxDistance2(p, frameBoxes + (size_t)current.left * 6);
      const ds_real dr = dsBoxDistance2(p, frameBoxes + (size_t)current.right * 6);
      const int leftFirst = dl <= dr;
      const int near = leftFirst ? current.left : current.right;
      const int far = leftFirst ? current.right : current.left;
      const ds_real dNear = leftFirst ? dl : dr;
      const ds_real dFar = leftFirst ? dr : dl;
      if (dNear <= limit) {
        next = near;
        if (dFar <= limit) {
          stack[sp] = far;
          stackDistance[sp] = dFar;
          ++sp;
        }
      }
    }
    if (next < 0) {
      const ds_real limit = band * pruneScale + pruneAbsolute;
      while (sp > 0 && next < 0) {
        --sp;
        if (stackDistance[sp] <= limit) {
          next = stack[sp];
        }
      }
    }
    node = next;
  }

  if (!overflow) {
    DsSurfaceHit hit;
    hit.triangle = -1;
    for (int j = 0; j < ties; ++j) {
      if (hit.triangle < 0 || tieTriangle[j] < hit.triangle) {
        hit.triangle = tieTriangle[j];
        hit.u = tieU[j];
        hit.v = tieV[j];
        hit.distance2 = (float)tieDistance[j];
      }
    }
    return hit;
  }

  // Pass 2: the smallest triangle index within the tie band of the smallest distance.
  const ds_real limit = band * pruneScale + pruneAbsolute;
  DsSurfaceHit hit;
  hit.triangle = -1;
  hit.u = 0.0f;
  hit.v = 0.0f;
  hit.distance2 = (float)best;
  sp = 0;
  node = root;
  while (node >= 0) {
    const DsBvhNode current = nodes[node];
    int next = -1;
    if (current.count > 0) {
      for (int k = current.first; k < current.first + current.count; ++k) {
        const int4 tri = leafTriangles[k];
        if (hit.triangle >= 0 && tri.w >= hit.triangle) {
          continue;
        }
        const ds_real d2 = dsTriangleDistance2(p, dsLoad3(pose, tri.x), dsLoad3(pose, tri.y),
                                               dsLoad3(pose, tri.z), &u, &v);
        if (d2 <= band) {
          hit.triangle = tri.w;
          hit.u = (float)u;
          hit.v = (float)v;
          hit.distance2 = (float)d2;
        }
      }
    } else {
      const ds_real dl = dsBoxDistance2(p, frameBoxes + (size_t)current.left * 6);
      const ds_real dr = dsBoxDistance2(p, frameBoxes + (size_t)current.right * 6);
      if (dl <= limit) {
        next = current.left;
        if (dr <= limit) {
          stack[sp] = current.right;
          ++sp;
        }
      } else if (dr <= limit) {
        next = current.right;
      }
    }
    if (next < 0 && sp > 0) {
      --sp;
      next = stack[sp];
    }
    node = next;
  }
  if (hit.triangle < 0) {
    // Unreachable (the triangle of pass 1's minimum is within the band); kept so a rounding
    // surprise still yields that triangle rather than no answer.
    const ds_real d2 = dsCandidateDistance2(p, pose, triangles, bestTriangle, &u, &v);
    hit.triangle = bestTriangle;
    hit.u = (float)u;
    hit.v = (float)v;
    hit.distance2 = (float)d2;
  }
  return hit;
}

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsBvhClosest(
    __global const float* poses, __global const int* triangles, __global const DsBvhNode* nodes,
    __global const int4* leafTriangles, __global const float* boxes, __global const float* points,
    __global const int* pointRoot, __global const DsSurfaceHit* seeds, __global DsSurfaceHit* hits,
    const DsBvhQueryParams params) {
  const int item = (int)get_global_id(0);
  if (item >= params.frameCount * params.pointCount) {
    return;
  }
  const int point = item % params.pointCount;
  hits[item] = dsBvhSearch(item, poses, triangles, nodes, leafTriangles, boxes, points, pointRoot,
                           seeds[point].triangle, params);
}

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsBvhClosestList(
    __global const float* poses, __global const int* triangles, __global const DsBvhNode* nodes,
    __global const int4* leafTriangles, __global const float* boxes, __global const float* points,
    __global const int* pointRoot, __global DsSurfaceHit* hits, const DsBvhQueryParams params,
    __global const int* search, const int searchCount) {
  const int id = (int)get_global_id(0);
  if (id >= searchCount) {
    return;
  }
  const int item = search[id];
  hits[item] = dsBvhSearch(item, poses, triangles, nodes, leafTriangles, boxes, points, pointRoot,
                           hits[item].triangle, params);
}
