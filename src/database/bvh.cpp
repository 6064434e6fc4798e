// SPDX-License-Identifier: Apache-2.0
// Exact closest triangle on the device: BVH refit per frame, FLANN warm start, pruned walk.
//
// Scheme. Once per setSurface (the driver topology and the mask are fixed for a bake):
//   1. One binary BVH per search class (each mask class with points; one over all triangles
//      for the unmasked points), built on the rest pose by median splits of the triangle
//      centroids along the longest axis, at most kLeafSize triangles per leaf. Only the tree
//      *structure* is kept: which triangles sit under which node. All trees share one node
//      array sorted by depth.
//   2. On the first chunk: a warm-start triangle per driven point, the triangle of its class
//      whose centroid on frame 0 is nearest to the point (a FLANN KD-tree per class, 1-NN).
//      After every chunk the seeds become the hits of the chunk's last frame (they only set
//      the first upper bound, so any triangle of the class is a valid seed).
// Per chunk of F frames, on the device (poses and points go up once per chunk):
//   3. Refit (dsBvhRefit, one launch per depth, deepest first): every node's box on every
//      frame is the min/max of the float coordinates of the vertices of its triangles (leaf)
//      or the union of its children's boxes. Min and max are exact in float, so each box
//      contains its triangles exactly.
//   4. Query (dsBvhClosest, one work item per frame and point p):
//      a. best = the computed squared distance to the seed triangle (an upper bound).
//      b. Pass 1: walk the class's tree nearest child first; a node is skipped when its box's
//         squared distance to p exceeds limit(best) = band(best) (1 + pruneRelative) +
//         pruneAbsolute, with band(best) = best + tieRelative best + tieAbsolute the tie band
//         of kernels/closest.cl; every triangle of a visited leaf lowers best. The walk keeps
//         the triangles within band(best) of the best so far (at most DS_BVH_TIES).
//      c. The answer is the smallest triangle index among those kept within band(final best)
//         (the tie rule of kernels/closest.cl). Only if more than DS_BVH_TIES triangles were
//         within the band at once does a second walk, with the final limit, find that index.
//
// Why it is exact (the same answer as computing every allowed triangle's distance with the
// kernels' formula and applying the tie rule). For any triangle t of the class, its true
// distance to p is at least the true distance of any box that contains t, and boxes contain
// their triangles exactly (step 3). The computed squared distances of triangles and boxes are
// each within a few roundings of (d^2 + S^2) of their true values (S the scene scale), which
// pruneRelative and pruneAbsolute exceed (DS_PRUNE_*: about 1e4 roundoffs in double, 16 in
// float). So a box is
// skipped only if every triangle in it has computed distance above band(best) >= best: in
// pass 1 the triangle of the smallest computed distance is never skipped, so best ends equal
// to the brute-force minimum of the computed distances. Every triangle within band(final best)
// lies in boxes within limit(final best) <= limit(best so far) of p, so pass 1 visits it too
// (and the second walk, if needed, as well): the triangles kept are exactly those within the
// final band, and the smallest index among them is the brute-force choice. The result
// does not depend on the seeds, the visiting order or the chunking; these only change how many
// boxes are opened. Far points are no special case: the bound and the boxes are the same
// quantities whatever the distance.
//
// Cost. Refit: one pass over the triangles and nodes per frame. Query: with a seed near the
// answer, the walk opens the leaves whose boxes reach within the best distance of p; on the
// W1-like scene of bench/bench_correction (cloth about two triangle sizes off the body)
// that is about 24 triangle distances and 40 box distances per point, against about 23
// candidates per point (each measured twice) plus the KD-tree builds and queries of the host
// search.

#include "bvh.h"

#include <algorithm>
#include <cstddef>
#include <numeric>

#include <flann/flann.hpp>

#include <drivenshape/error.h>

namespace drivenshape::correction {
namespace {

struct BuildNode {
  int left = -1;
  int right = -1;
  int first = 0;  ///< range of the class's permuted triangles
  int count = 0;
  int depth = 0;
};

/// Builds one tree over `triangles` (permuted in place into leaf order); returns its nodes,
/// root first, children as indices into the returned vector.
std::vector<BuildNode> buildTree(std::vector<int>& triangles, const Eigen::MatrixX3f& centroids,
                                 int leafSize) {
  std::vector<BuildNode> nodes;
  nodes.push_back({-1, -1, 0, static_cast<int>(triangles.size()), 0});
  std::vector<int> pending = {0};
  while (!pending.empty()) {
    const int n = pending.back();
    pending.pop_back();
    const int first = nodes[static_cast<std::size_t>(n)].first;
    const int count = nodes[static_cast<std::size_t>(n)].count;
    if (count <= leafSize) {
      continue;
    }
    const auto begin = triangles.begin() + first;
    const auto end = begin + count;
    Eigen::Vector3f low = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
    Eigen::Vector3f high = -low;
    for (auto it = begin; it != end; ++it) {
      low = low.cwiseMin(centroids.row(*it).transpose());
      high = high.cwiseMax(centroids.row(*it).transpose());
    }
    int axis = 0;
    (high - low).maxCoeff(&axis);
    const int half = count / 2;
    std::nth_element(begin, begin + half, end, [&](int a, int b) {
      const float ca = centroids(a, axis);
      const float cb = centroids(b, axis);
      return ca < cb || (ca == cb && a < b);
    });
    const int depth = nodes[static_cast<std::size_t>(n)].depth + 1;
    const int left = static_cast<int>(nodes.size());
    nodes.push_back({-1, -1, first, half, depth});
    nodes.push_back({-1, -1, first + half, count - half, depth});
    nodes[static_cast<std::size_t>(n)].left = left;
    nodes[static_cast<std::size_t>(n)].right = left + 1;
    nodes[static_cast<std::size_t>(n)].count = 0;
    pending.push_back(left);
    pending.push_back(left + 1);
  }
  return nodes;
}

}  // namespace

BvhTables buildBvh(const Mesh& driver, const BindingMask& mask, int leafSize) {
  const int triangleCount = driver.triangleCount();
  BvhTables bvh;
  // Search classes with points, in the order of CandidateSearch: mask classes, then "all".
  std::vector<BvhTables::SearchClass> classes(static_cast<std::size_t>(mask.classCount()));
  BvhTables::SearchClass everything;
  for (int c = 0; c < mask.classCount(); ++c) {
    classes[static_cast<std::size_t>(c)].triangles = mask.classTriangles(c);
  }
  for (int i = 0; i < mask.drivenVertexCount(); ++i) {
    const int c = mask.vertexClass(i);
    (c < 0 ? everything : classes[static_cast<std::size_t>(c)]).points.push_back(i);
  }
  if (!everything.points.empty()) {
    everything.triangles.resize(static_cast<std::size_t>(triangleCount));
    std::iota(everything.triangles.begin(), everything.triangles.end(), 0);
    classes.push_back(std::move(everything));
  }
  classes.erase(std::remove_if(classes.begin(), classes.end(),
                               [](const BvhTables::SearchClass& c) { return c.points.empty(); }),
                classes.end());

  Eigen::MatrixX3f centroids(triangleCount, 3);
  for (int t = 0; t < triangleCount; ++t) {
    centroids.row(t) = (driver.positions.row(driver.triangles(t, 0)) +
                        driver.positions.row(driver.triangles(t, 1)) +
                        driver.positions.row(driver.triangles(t, 2))) /
                       3.0f;
  }

  // Build every tree, then order all nodes by depth (stable: tree by tree, creation order).
  struct Placed {
    int tree;
    int local;
    int depth;
  };
  std::vector<std::vector<BuildNode>> trees;
  std::vector<std::vector<int>> orders;
  std::vector<Placed> placed;
  for (std::size_t c = 0; c < classes.size(); ++c) {
    std::vector<int> order = classes[c].triangles;
    trees.push_back(buildTree(order, centroids, std::max(leafSize, 1)));
    orders.push_back(std::move(order));
    for (std::size_t n = 0; n < trees.back().size(); ++n) {
      placed.push_back({static_cast<int>(c), static_cast<int>(n), trees.back()[n].depth});
    }
  }
  std::stable_sort(placed.begin(), placed.end(),
                   [](const Placed& a, const Placed& b) { return a.depth < b.depth; });
  std::vector<std::vector<int>> globalId(trees.size());
  for (std::size_t c = 0; c < trees.size(); ++c) {
    globalId[c].resize(trees[c].size());
  }
  for (std::size_t g = 0; g < placed.size(); ++g) {
    globalId[static_cast<std::size_t>(placed[g].tree)][static_cast<std::size_t>(placed[g].local)] =
        static_cast<int>(g);
  }
  const int depthCount = placed.empty() ? 0 : placed.back().depth + 1;
  if (depthCount > DS_BVH_MAX_DEPTH) {
    DS_THROW(kInternal, "closest triangle: a BVH of depth ", depthCount, " exceeds the walk's ",
             DS_BVH_MAX_DEPTH, " levels (a bug: median splits keep it logarithmic)");
  }
  bvh.levelStart.assign(static_cast<std::size_t>(depthCount) + 1, 0);
  for (const Placed& p : placed) {
    ++bvh.levelStart[static_cast<std::size_t>(p.depth) + 1];
  }
  std::partial_sum(bvh.levelStart.begin(), bvh.levelStart.end(), bvh.levelStart.begin());

  bvh.nodes.resize(placed.size());
  for (std::size_t g = 0; g < placed.size(); ++g) {
    const std::size_t c = static_cast<std::size_t>(placed[g].tree);
    const BuildNode& node = trees[c][static_cast<std::size_t>(placed[g].local)];
    DsBvhNode& out = bvh.nodes[g];
    out.left = node.left < 0 ? -1 : globalId[c][static_cast<std::size_t>(node.left)];
    out.right = node.right < 0 ? -1 : globalId[c][static_cast<std::size_t>(node.right)];
    out.first = 0;
    out.count = 0;
    if (node.left < 0) {
      out.first = static_cast<int>(bvh.leafTriangles.size() / 4);
      out.count = node.count;
      for (int k = node.first; k < node.first + node.count; ++k) {
        const int t = orders[c][static_cast<std::size_t>(k)];
        bvh.leafTriangles.insert(
            bvh.leafTriangles.end(),
            {driver.triangles(t, 0), driver.triangles(t, 1), driver.triangles(t, 2), t});
      }
    }
  }
  bvh.pointRoot.assign(static_cast<std::size_t>(mask.drivenVertexCount()), -1);
  for (std::size_t c = 0; c < classes.size(); ++c) {
    for (int i : classes[c].points) {
      bvh.pointRoot[static_cast<std::size_t>(i)] = globalId[c][0];
    }
  }
  bvh.classes = std::move(classes);
  return bvh;
}

void seedTriangles(const BvhTables& bvh, const std::int32_t* triangles, const float* pose,
                   const float* points, std::vector<std::int32_t>& seeds) {
  seeds.assign(bvh.pointRoot.size(), 0);
  std::vector<float> centroids;
  std::vector<float> queries;
  for (const BvhTables::SearchClass& cls : bvh.classes) {
    const std::size_t n = cls.triangles.size();
    centroids.resize(3 * n);
    for (std::size_t j = 0; j < n; ++j) {
      const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(cls.triangles[j]);
      for (std::size_t a = 0; a < 3; ++a) {
        centroids[3 * j + a] = (pose[3 * static_cast<std::size_t>(tri[0]) + a] +
                                pose[3 * static_cast<std::size_t>(tri[1]) + a] +
                                pose[3 * static_cast<std::size_t>(tri[2]) + a]) /
                               3.0f;
      }
    }
    flann::KDTreeSingleIndex<flann::L2<float>> index(flann::Matrix<float>(centroids.data(), n, 3),
                                                     flann::KDTreeSingleIndexParams(8));
    index.buildIndex();
    const std::size_t m = cls.points.size();
    queries.resize(3 * m);
    for (std::size_t r = 0; r < m; ++r) {
      std::copy_n(points + 3 * static_cast<std::size_t>(cls.points[r]), 3, &queries[3 * r]);
    }
    std::vector<std::size_t> nearest(m);
    std::vector<float> distances(m);
    flann::Matrix<std::size_t> nearestMatrix(nearest.data(), m, 1);
    flann::Matrix<float> distanceMatrix(distances.data(), m, 1);
    index.knnSearch(flann::Matrix<float>(queries.data(), m, 3), nearestMatrix, distanceMatrix, 1,
                    flann::SearchParams(-1, 0.0f, false));
    for (std::size_t r = 0; r < m; ++r) {
      seeds[static_cast<std::size_t>(cls.points[r])] = cls.triangles[nearest[r]];
    }
  }
}

}  // namespace drivenshape::correction
