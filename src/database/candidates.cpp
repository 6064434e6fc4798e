// SPDX-License-Identifier: Apache-2.0
// Candidate triangles for the exact closest-triangle search.
//
// Scheme (per frame and per mask class; the pose changes every frame, so the tree does too):
//
//   1. Pieces. Every allowed triangle is cut by longest-edge bisection until each piece's
//      radius is at most kSplitFactor x the median triangle radius of the class (at most
//      kMaxPiecesPerTriangle pieces per triangle). A piece p has a centroid c_p (rounded to
//      float, as FLANN stores it) and a radius r_p = the largest distance from c_p to its
//      three corners (in double). Most triangles of a cloth-like mesh are one piece; long
//      slivers and stretched triangles become several, so one big triangle no longer inflates
//      every search radius. rmax = the largest r_p.
//   2. A FLANN KD-tree (KDTreeSingleIndex, exact search: eps = 0) over the piece centroids.
//   3. Clusters. The points of the class, in Morton order of this frame's positions, are cut
//      into runs of at most kClusterSize points that stay within the split radius of the run's
//      first point. A cluster has a centre o (float) and a spread rho = max |d_i - o|.
//   4. Upper bounds. For each point d_i of a cluster, U_i = the exact distance from d_i to the
//      triangle of the piece nearest o (1-NN query). Any triangle's distance bounds the
//      minimum D*_i from above.
//   5. One radius query per cluster around o, radius R = max_i U_i + rho + rmax.
//   6. Per point: U_i is lowered to the exact distance to the triangle of the nearest piece
//      found, then triangle t is kept if one of its found pieces has |d_i - c_p| <= U_i + r_p.
//
// Why the closest triangle is always kept. Let t* be a closest triangle of point d (= d_i),
// q* its closest point, |d - q*| = D* <= U_i. The pieces of t* cover t*, so q* lies in some
// piece p*; a piece is the convex hull of its corners and |x - c| is convex in x, so
// |q* - c_p*| <= r_p*. Hence
//   |d - c_p*| <= |d - q*| + |q* - c_p*| <= D* + r_p* <= U_i + r_p*            (step 6 keeps t*)
//   |o - c_p*| <= |o - d| + |d - c_p*| <= rho + U_i + rmax <= R                (step 5 finds p*)
// where step 6 uses the lowered U_i, which is still >= D* (it is a real triangle's distance),
// and step 5 the first U_i, which is >= the lowered one. The same holds for every triangle at
// distance D* (ties) and, with the slack below, for every triangle within the double-precision
// tie band of the exact step (distance at most D* (1 + 1e-12) + sqrt(DS_TIE_SCALE2_DOUBLE) *
// sceneScale), so the tie-break among candidates equals the tie-break among all allowed
// triangles. Far points are no special case: U_i grows, R grows with it, the bound holds.
//
// Rounding. FLANN works in float: its squared distances carry a relative error of a few 1e-7,
// and its tree pruning compares float box distances with the same relative error. The U_i,
// r_p and the step-6 distances are computed in double from exact float inputs (r_p from the
// float centroid FLANN holds; bisection midpoints in double), so the errors are relative ones
// of order 1e-7 in FLANN plus ~1e-16 of the coordinates' magnitude elsewhere. Every comparison
// therefore uses
//   bound(r) = (U + r) (1 + kRelativeSlack) + kAbsoluteSlack * frameScale
//              + 2 sqrt(DS_TIE_SCALE2_DOUBLE) * sceneScale     (the reach of the tie band)
// with kRelativeSlack = 1e-5 (50x the float error) and frameScale the largest coordinate
// magnitude in the frame, and the radius query asks for bound(rmax)^2 (1 + 1e-6) because FLANN
// keeps only distances strictly below the radius.
//
// Cost. Per frame and class: the pieces, a tree build, one 1-NN query and one radius query per
// cluster, then per point one pass over the cluster's found pieces and two exact distances.
// Frames run in parallel on host threads.

#include "candidates.h"
#include "finite.h"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstddef>
#include <limits>

#include <flann/flann.hpp>

#include <drivenshape/error.h>

#include "parallel.h"

#include "triangle_distance.h"

namespace drivenshape::correction {
namespace {

constexpr std::size_t kClusterSize = 8;
constexpr int kLeafSize = 8;
constexpr double kSplitFactor = 1.0;
constexpr int kMaxPiecesPerTriangle = 64;
constexpr double kRelativeSlack = 1e-5;
constexpr double kAbsoluteSlack = 1e-9;

double frameMagnitude(const float* xyz, long count) {
  float largest = 0.0f;
  for (long i = 0; i < 3 * count; ++i) {
    largest = std::max(largest, std::fabs(xyz[i]));
  }
  return static_cast<double>(largest);
}

}  // namespace

void checkFinite(const char* stage, const char* what, int frameCount, int count,
                 const float* data) {
  if (data == nullptr) {
    return;
  }
  const std::size_t stride = 3 * static_cast<std::size_t>(count);
  for (int f = 0; f < frameCount; ++f) {
    const float* frame = data + static_cast<std::size_t>(f) * stride;
    const std::size_t k = firstNonFinite(frame, stride);
    if (k < stride) {
      DS_THROW(kNumerical, stage, ": frame ", f, " of the chunk: ", what, " ", k / 3, " has a ",
               std::isnan(frame[k]) ? "NaN" : "infinite", " coordinate (axis ", "xyz"[k % 3],
               "); the input or the blend that produced it is broken");
    }
  }
}

void checkTransfer(const CandidateSearch& search, int frameCount, const SurfaceHit* hits,
                   const float* fromPoses, const float* toPoses, const float* points,
                   const float* out) {
  search.checkChunk("transfer", frameCount,
                    hits != nullptr && fromPoses != nullptr && toPoses != nullptr &&
                        points != nullptr && out != nullptr);
  checkFinite("transfer", "driver vertex of the 'from' pose", frameCount, search.vertexCount(),
              fromPoses);
  checkFinite("transfer", "driver vertex of the 'to' pose", frameCount, search.vertexCount(),
              toPoses);
  checkFinite("transfer", "driven point", frameCount, search.pointCount(), points);
  checkHits("transfer", search.triangleCount(),
            static_cast<std::size_t>(frameCount) * search.pointCount(), search.pointCount(), hits);
}

void checkHits(const char* stage, int triangleCount, std::size_t count, int perFrame,
               const SurfaceHit* hits) {
  if (hits == nullptr) {
    return;
  }
  for (std::size_t k = 0; k < count; ++k) {
    const int t = hits[k].triangle;
    if (t < 0 || t >= triangleCount || !std::isfinite(hits[k].u) || !std::isfinite(hits[k].v)) {
      DS_THROW(kInput, stage, ": frame ", k / static_cast<std::size_t>(perFrame),
               " of the chunk: point ", k % static_cast<std::size_t>(perFrame),
               " has hit triangle ", t, " (u ", hits[k].u, ", v ", hits[k].v, "); the driver has ",
               triangleCount, " triangles; were the hits made for another surface?");
    }
  }
}

void checkRebuild(const CandidateSearch& search, int frameCount, const SurfaceHit* hits,
                  const float* toPoses, const float* local, const float* out) {
  search.checkChunk("rebuild", frameCount,
                    hits != nullptr && toPoses != nullptr && local != nullptr && out != nullptr);
  checkFinite("rebuild", "driver vertex of the 'to' pose", frameCount, search.vertexCount(),
              toPoses);
  checkFinite("rebuild", "local coordinates of driven point", frameCount, search.pointCount(),
              local);
  if (frameCount > 0) {
    checkHits("rebuild", search.triangleCount(), static_cast<std::size_t>(search.pointCount()),
              std::max(search.pointCount(), 1), hits);
  }
}

void checkOffset(float offset) {
  if (!std::isfinite(offset) || offset < 0.0f) {
    DS_THROW(kInput, "penetration resolution: the offset is ", offset,
             "; it must be a finite distance >= 0 in scene units");
  }
}

void checkExitFade(float fade) {
  if (!std::isfinite(fade) || fade < 0.0f) {
    DS_THROW(kInput, "penetration resolution: the exit fade is ", fade,
             "; it must be a finite number >= 0 (0 = off)");
  }
}

void checkSides(const std::vector<std::int8_t>& sides, int pointCount) {
  if (!sides.empty() && sides.size() != static_cast<std::size_t>(pointCount)) {
    DS_THROW(kInput, "side table: ", sides.size(), " entries for ", pointCount,
             " driven points; give one side per point (or none)");
  }
  for (std::size_t i = 0; i < sides.size(); ++i) {
    if (sides[i] != kSideOutside && sides[i] != kSideInside) {
      DS_THROW(kInput, "side table: driven point ", i, " has side ", static_cast<int>(sides[i]),
               "; a side is ", static_cast<int>(kSideOutside), " (outside) or ",
               static_cast<int>(kSideInside), " (inside)");
    }
  }
}

void checkResolve(const CandidateSearch& search, int frameCount, const float* poses,
                  const SurfaceHit* hits, float offset, const float* points) {
  search.checkChunk("penetration resolution", frameCount,
                    poses != nullptr && hits != nullptr && points != nullptr);
  checkOffset(offset);
  checkFinite("penetration resolution", "driver vertex", frameCount, search.vertexCount(), poses);
  checkFinite("penetration resolution", "driven point", frameCount, search.pointCount(), points);
  checkHits("penetration resolution", search.triangleCount(),
            static_cast<std::size_t>(frameCount) * search.pointCount(),
            std::max(search.pointCount(), 1), hits);
}

void CandidateSearch::setSurface(const Mesh& driver, const BindingMask& mask) {
  const int vertexCount = driver.vertexCount();
  const int triangleCount = driver.triangleCount();
  if (triangleCount == 0) {
    DS_THROW(kInput, "correction: the driver mesh has no triangles (", driver.faceCount(),
             " faces); it needs polygons of three or more vertices");
  }
  std::vector<std::int32_t> triangles(3 * static_cast<std::size_t>(triangleCount));
  for (int t = 0; t < triangleCount; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int v = driver.triangles(t, k);
      if (v < 0 || v >= vertexCount) {
        DS_THROW(kInput, "correction: driver triangle ", t, " names vertex ", v,
                 " but the driver has ", vertexCount, " vertices");
      }
      triangles[3 * static_cast<std::size_t>(t) + k] = v;
    }
  }
  std::vector<SearchClass> classes(static_cast<std::size_t>(mask.classCount()));
  for (int c = 0; c < mask.classCount(); ++c) {
    for (int t : mask.classTriangles(c)) {
      if (t < 0 || t >= triangleCount) {
        DS_THROW(kInput, "correction: binding mask class ", c, " names driver triangle ", t,
                 " but the driver has ", triangleCount,
                 " triangles; was the mask made for another driver mesh?");
      }
    }
    classes[static_cast<std::size_t>(c)].triangles = mask.classTriangles(c);
  }
  SearchClass everything;
  for (int i = 0; i < mask.drivenVertexCount(); ++i) {
    const int c = mask.vertexClass(i);
    (c < 0 ? everything : classes[static_cast<std::size_t>(c)]).points.push_back(i);
  }
  if (!everything.points.empty()) {
    everything.triangles.resize(static_cast<std::size_t>(triangleCount));
    for (int t = 0; t < triangleCount; ++t) {
      everything.triangles[static_cast<std::size_t>(t)] = t;
    }
    classes.push_back(std::move(everything));
  }
  classes.erase(std::remove_if(classes.begin(), classes.end(),
                               [](const SearchClass& c) { return c.points.empty(); }),
                classes.end());

  double scale = 1.0;
  if (vertexCount > 0) {
    const Bounds bounds = computeBounds(driver.positions.data(), vertexCount);
    scale = std::max(static_cast<double>(bounds.diagonal()),
                     frameMagnitude(driver.positions.data(), vertexCount));
    if (!(scale > 0.0) || !std::isfinite(scale)) {
      scale = 1.0;
    }
  }

  mVertexCount = vertexCount;
  mPointCount = mask.drivenVertexCount();
  mSceneScale = scale;
  mTriangles = std::move(triangles);
  mClasses = std::move(classes);
  mReady = true;
}

void CandidateSearch::checkChunk(const char* stage, int frameCount, bool buffersPresent) const {
  if (!mReady) {
    DS_THROW(kInternal, stage, ": setSurface() must be called first");
  }
  if (frameCount < 0) {
    DS_THROW(kInternal, stage, ": negative frame count ", frameCount);
  }
  if (frameCount > 0 && !buffersPresent) {
    DS_THROW(kInternal, stage, ": called with a null buffer");
  }
  const long long widest = 3LL * std::max(mVertexCount, mPointCount) + 3;
  if (static_cast<long long>(frameCount) * widest > INT_MAX) {
    DS_THROW(kInput, stage, ": a chunk of ", frameCount, " frames of ",
             std::max(mVertexCount, mPointCount),
             " vertices is too large for one launch; evaluate fewer frames per call");
  }
}

namespace {

/// The pieces of one class on one frame: every allowed triangle, split by longest-edge
/// bisection until each piece's radius is at most the target (see the scheme above).
///
///   parent    P ints     the triangle a piece belongs to
///   centroid  P x 3      float, as FLANN stores it
///   radius    P          largest distance from the float centroid to the piece's corners
struct Pieces {
  std::vector<int> parent;
  std::vector<float> centroid;
  std::vector<double> radius;
  double largest = 0.0;

  void clear() {
    parent.clear();
    centroid.clear();
    radius.clear();
    largest = 0.0;
  }

  /// Radius of (a, b, c) about its float centroid; sets the centroid.
  static double measure(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                        const Eigen::Vector3d& c, Eigen::Vector3f& centroid) {
    centroid = ((a + b + c) / 3.0).cast<float>();
    const Eigen::Vector3d cd = centroid.cast<double>();
    return std::sqrt(
        std::max({(a - cd).squaredNorm(), (b - cd).squaredNorm(), (c - cd).squaredNorm()}));
  }

  void add(int triangle, const Eigen::Vector3f& center, double r) {
    parent.push_back(triangle);
    centroid.insert(centroid.end(), {center.x(), center.y(), center.z()});
    radius.push_back(r);
    largest = std::max(largest, r);
  }
};

/// FLANN result set for the radius query: the indices of every piece strictly within the radius.
class Collect final : public flann::ResultSet<float> {
 public:
  Collect(float radius2, std::vector<std::size_t>& found) : mRadius2(radius2), mFound(found) {}
  bool full() const override { return true; }
  float worstDist() const override { return mRadius2; }
  void addPoint(float dist, std::size_t index) override {
    if (dist < mRadius2) {
      mFound.push_back(index);
    }
  }

 private:
  float mRadius2;
  std::vector<std::size_t>& mFound;
};

/// 30-bit Morton code of p in the box [low, low + extent] (10 bits per axis).
std::uint32_t mortonCode(const float* p, const Eigen::Vector3f& low, float scale) {
  std::uint32_t code = 0;
  std::uint32_t cell[3];
  for (int a = 0; a < 3; ++a) {
    const float x = (p[a] - low[a]) * scale;
    cell[a] = static_cast<std::uint32_t>(std::min(std::max(x, 0.0f), 1023.0f));
  }
  for (int bit = 9; bit >= 0; --bit) {
    for (int a = 0; a < 3; ++a) {
      code = (code << 1) | ((cell[a] >> bit) & 1u);
    }
  }
  return code;
}

/// The FLANN tree over the piece centroids.
using PieceIndex = flann::KDTreeSingleIndex<flann::L2<float>>;

/// bound(r) of the scheme above for the upper bound U = `upper`.
double candidateBound(double upper, double r, double absoluteSlack) {
  return (upper + r) * (1.0 + kRelativeSlack) + absoluteSlack;
}

/// The driver triangles on one frame's pose.
struct PoseTriangles {
  const float* pose;                           // Vp x 3
  const std::vector<std::int32_t>& triangles;  // T x 3 vertex ids

  /// Corner k of triangle t, in double.
  Eigen::Vector3d corner(int t, int k) const {
    return loadPoint(pose,
                     triangles[3 * static_cast<std::size_t>(t) + static_cast<std::size_t>(k)]);
  }

  /// The exact distance from p to triangle t.
  double distance(const Eigen::Vector3d& p, int t) const {
    double u = 0.0;
    double v = 0.0;
    return std::sqrt(triangleDistance2(p, corner(t, 0), corner(t, 1), corner(t, 2), u, v));
  }
};

/// Work buffers of one frame's search, reused from class to class.
///
///   order         m        (Morton code, point) of the class's points, sorted
///   clusterStart  C + 1    cluster c is order[clusterStart[c] .. clusterStart[c+1]-1]
///   centers       C x 3    cluster centres o (float, as FLANN takes them)
///   spread        C        rho = max |d_i - o| over the cluster
///   nearIndices   C        the piece nearest each centre
///   uppers        <= 8     U_i of the current cluster's points
///   found         -        pieces within the current cluster's radius R
struct SearchScratch {
  Pieces pieces;
  std::vector<double> radii;
  std::vector<std::array<Eigen::Vector3d, 3>> stack;
  std::vector<std::pair<std::uint32_t, int>> order;
  std::vector<float> centers;
  std::vector<double> spread;
  std::vector<std::size_t> clusterStart;
  std::vector<std::size_t> nearIndices;
  std::vector<float> nearDists;
  std::vector<double> uppers = std::vector<double>(kClusterSize);
  std::vector<std::size_t> found;
  std::vector<double> centroidDistance2;
  std::vector<std::int32_t> kept;
};

/// The split target of a class: kSplitFactor times the median triangle radius (infinite when
/// that is 0, i.e. mostly degenerate triangles: nothing to split). `radii` is scratch.
double pieceTarget(const PoseTriangles& surface, const std::vector<int>& triangles,
                   std::vector<double>& radii) {
  const std::size_t n = triangles.size();
  radii.resize(n);
  Eigen::Vector3f center;
  for (std::size_t j = 0; j < n; ++j) {
    const int t = triangles[j];
    radii[j] =
        Pieces::measure(surface.corner(t, 0), surface.corner(t, 1), surface.corner(t, 2), center);
  }
  std::nth_element(radii.begin(), radii.begin() + static_cast<std::ptrdiff_t>(n / 2), radii.end());
  double target = kSplitFactor * radii[n / 2];
  if (!(target > 0.0)) {
    target = std::numeric_limits<double>::infinity();  // mostly points: nothing to split
  }
  return target;
}

/// Adds the pieces of triangle t: longest-edge bisection until a piece's radius is at most
/// `target`, at most kMaxPiecesPerTriangle pieces. `stack` is scratch.
void splitTriangle(const PoseTriangles& surface, int t, double target,
                   std::vector<std::array<Eigen::Vector3d, 3>>& stack, Pieces& pieces) {
  Eigen::Vector3f center;
  stack.clear();
  stack.push_back({surface.corner(t, 0), surface.corner(t, 1), surface.corner(t, 2)});
  int budget = kMaxPiecesPerTriangle;
  while (!stack.empty()) {
    const std::array<Eigen::Vector3d, 3> piece = stack.back();
    stack.pop_back();
    const double r = Pieces::measure(piece[0], piece[1], piece[2], center);
    if (r <= target || budget <= 1 + static_cast<int>(stack.size())) {
      pieces.add(t, center, r);
      --budget;
      continue;
    }
    // Bisect the longest edge (k, k+1) at its midpoint.
    int k = 0;
    double longest = -1.0;
    for (int e = 0; e < 3; ++e) {
      const double length =
          (piece[static_cast<std::size_t>((e + 1) % 3)] - piece[static_cast<std::size_t>(e)])
              .squaredNorm();
      if (length > longest) {
        longest = length;
        k = e;
      }
    }
    const Eigen::Vector3d& p0 = piece[static_cast<std::size_t>(k)];
    const Eigen::Vector3d& p1 = piece[static_cast<std::size_t>((k + 1) % 3)];
    const Eigen::Vector3d& p2 = piece[static_cast<std::size_t>((k + 2) % 3)];
    const Eigen::Vector3d middle = 0.5 * (p0 + p1);
    stack.push_back({p0, middle, p2});
    stack.push_back({middle, p1, p2});
  }
}

/// The class's points as (Morton code, point) in Morton order of this frame's positions.
void mortonOrder(const float* points, const std::vector<int>& classPoints,
                 std::vector<std::pair<std::uint32_t, int>>& order) {
  const std::size_t m = classPoints.size();
  Eigen::Vector3f low = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f high = -low;
  for (int point : classPoints) {
    const Eigen::Vector3f p(points + 3 * static_cast<std::size_t>(point));
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  const float extent = (high - low).maxCoeff();
  const float scale = extent > 0.0f ? 1023.0f / extent : 0.0f;
  order.resize(m);
  for (std::size_t r = 0; r < m; ++r) {
    const int point = classPoints[r];
    order[r] = {mortonCode(points + 3 * static_cast<std::size_t>(point), low, scale), point};
  }
  std::sort(order.begin(), order.end());
}

/// Cuts s.order into clusters and sets s.clusterStart (with the end appended), s.centers and
/// s.spread; returns the cluster count. Consecutive points join a cluster while they stay
/// within `join` of its first point (the Morton order jumps now and then), at most
/// kClusterSize of them.
std::size_t clusterPoints(const float* points, double join, SearchScratch& s) {
  const std::size_t m = s.order.size();
  s.clusterStart.clear();
  for (std::size_t r = 0; r < m; ++r) {
    if (s.clusterStart.empty() || r - s.clusterStart.back() >= kClusterSize ||
        (loadPoint(points, s.order[r].second) -
         loadPoint(points, s.order[s.clusterStart.back()].second))
                .norm() > join) {
      s.clusterStart.push_back(r);
    }
  }
  const std::size_t clusterCount = s.clusterStart.size();
  s.clusterStart.push_back(m);
  s.centers.resize(3 * clusterCount);
  s.spread.resize(clusterCount);
  for (std::size_t c = 0; c < clusterCount; ++c) {
    const std::size_t first = s.clusterStart[c];
    const std::size_t last = s.clusterStart[c + 1];
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (std::size_t r = first; r < last; ++r) {
      sum += loadPoint(points, s.order[r].second);
    }
    const Eigen::Vector3f center32 = (sum / static_cast<double>(last - first)).cast<float>();
    const Eigen::Vector3d center64 = center32.cast<double>();
    double rho = 0.0;
    for (std::size_t r = first; r < last; ++r) {
      rho = std::max(rho, (loadPoint(points, s.order[r].second) - center64).norm());
    }
    s.centers[3 * c] = center32.x();
    s.centers[3 * c + 1] = center32.y();
    s.centers[3 * c + 2] = center32.z();
    s.spread[c] = rho;
  }
  return clusterCount;
}

/// s.nearIndices: the piece nearest each cluster centre (exact 1-NN query).
void nearestPieces(const PieceIndex& index, const flann::SearchParams& params,
                   std::size_t clusterCount, SearchScratch& s) {
  s.nearIndices.resize(clusterCount);
  s.nearDists.resize(clusterCount);
  flann::Matrix<std::size_t> nearIndexMatrix(s.nearIndices.data(), clusterCount, 1);
  flann::Matrix<float> nearDistMatrix(s.nearDists.data(), clusterCount, 1);
  index.knnSearch(flann::Matrix<float>(s.centers.data(), clusterCount, 3), nearIndexMatrix,
                  nearDistMatrix, 1, params);
}

/// Steps 4 and 5 for cluster c: s.uppers gets U_i of its points (the exact distance to the
/// triangle of the piece nearest the centre), s.found every piece within R of the centre.
void findClusterPieces(const PieceIndex& index, const flann::SearchParams& params,
                       const PoseTriangles& surface, const float* points, std::size_t c,
                       double absoluteSlack, SearchScratch& s) {
  const std::size_t first = s.clusterStart[c];
  const std::size_t last = s.clusterStart[c + 1];
  const int nearest = s.pieces.parent[s.nearIndices[c]];
  double reach = 0.0;
  for (std::size_t r = first; r < last; ++r) {
    s.uppers[r - first] = surface.distance(loadPoint(points, s.order[r].second), nearest);
    reach = std::max(reach, s.uppers[r - first]);
  }
  const double upper = reach + s.spread[c];
  const double radius = candidateBound(upper, s.pieces.largest, absoluteSlack);
  s.found.clear();
  Collect collect(
      static_cast<float>(radius * radius * (1.0 + 1e-6)) + std::numeric_limits<float>::min(),
      s.found);
  index.findNeighbors(collect, &s.centers[3 * c], params);
}

/// Step 6 for one point: s.kept gets the triangles of the found pieces within the bound of
/// `point` (sorted, without repeats), with U_i (`firstUpper` from the cluster's search)
/// lowered to the distance to the triangle of the nearest found piece. Throws Error(kInternal)
/// if none is kept.
void keepCandidates(const PoseTriangles& surface, const float* points, int point, double firstUpper,
                    double absoluteSlack, SearchScratch& s) {
  const Eigen::Vector3d p = loadPoint(points, point);
  // Refine U_i with the triangle of the nearest found piece (any triangle is an upper
  // bound; the search above already covers the larger one).
  double nearestDistance2 = std::numeric_limits<double>::infinity();
  std::size_t nearestPiece = 0;
  s.centroidDistance2.resize(s.found.size());
  for (std::size_t j = 0; j < s.found.size(); ++j) {
    const float* cp = &s.pieces.centroid[3 * s.found[j]];
    const double d2 = (p - Eigen::Vector3d(cp[0], cp[1], cp[2])).squaredNorm();
    s.centroidDistance2[j] = d2;
    if (d2 < nearestDistance2) {
      nearestDistance2 = d2;
      nearestPiece = s.found[j];
    }
  }
  double upper = firstUpper;
  if (!s.found.empty()) {
    upper = std::min(upper, surface.distance(p, s.pieces.parent[nearestPiece]));
  }
  s.kept.clear();
  for (std::size_t j = 0; j < s.found.size(); ++j) {
    const double limit = candidateBound(upper, s.pieces.radius[s.found[j]], absoluteSlack);
    if (s.centroidDistance2[j] <= limit * limit) {
      s.kept.push_back(s.pieces.parent[s.found[j]]);
    }
  }
  if (s.kept.empty()) {
    DS_THROW(kInternal, "closest triangle: no candidate triangle for driven point ", point,
             "; the candidate bound failed (a bug)");
  }
  std::sort(s.kept.begin(), s.kept.end());
  s.kept.erase(std::unique(s.kept.begin(), s.kept.end()), s.kept.end());
}

}  // namespace

void CandidateSearch::findFrame(const float* pose, const float* points, const std::uint8_t* active,
                                double frameScale, FrameCandidates& out) const {
  out.count.assign(static_cast<std::size_t>(mPointCount), 0);
  out.offset.assign(static_cast<std::size_t>(mPointCount), 0);
  out.triangles.clear();
  const double absoluteSlack =
      kAbsoluteSlack * frameScale + 2.0 * std::sqrt(DS_TIE_SCALE2_DOUBLE) * mSceneScale;
  const PoseTriangles surface{pose, mTriangles};

  SearchScratch s;
  std::vector<int> activePoints;
  for (const SearchClass& cls : mClasses) {
    const std::vector<int>* classPoints = &cls.points;
    if (active != nullptr) {
      activePoints.clear();
      for (const int point : cls.points) {
        if (active[point] != 0) {
          activePoints.push_back(point);
        }
      }
      if (activePoints.empty()) {
        continue;
      }
      classPoints = &activePoints;
    }
    // Pieces, and the tree over their centroids.
    const double target = pieceTarget(surface, cls.triangles, s.radii);
    s.pieces.clear();
    for (const int t : cls.triangles) {
      splitTriangle(surface, t, target, s.stack, s.pieces);
    }
    const std::size_t pieceCount = s.pieces.parent.size();
    PieceIndex index(flann::Matrix<float>(s.pieces.centroid.data(), pieceCount, 3),
                     flann::KDTreeSingleIndexParams(kLeafSize));
    index.buildIndex();

    // Clusters of nearby points (Morton order of this frame's positions).
    mortonOrder(points, *classPoints, s.order);
    const double join = std::isfinite(target) ? target : s.pieces.largest;
    const std::size_t clusterCount = clusterPoints(points, join, s);
    const flann::SearchParams params(-1, 0.0f, false);
    nearestPieces(index, params, clusterCount, s);

    for (std::size_t c = 0; c < clusterCount; ++c) {
      findClusterPieces(index, params, surface, points, c, absoluteSlack, s);
      const std::size_t first = s.clusterStart[c];
      const std::size_t last = s.clusterStart[c + 1];
      for (std::size_t r = first; r < last; ++r) {
        const int point = s.order[r].second;
        keepCandidates(surface, points, point, s.uppers[r - first], absoluteSlack, s);
        out.offset[static_cast<std::size_t>(point)] =
            static_cast<std::int32_t>(out.triangles.size());
        out.count[static_cast<std::size_t>(point)] = static_cast<std::int32_t>(s.kept.size());
        out.triangles.insert(out.triangles.end(), s.kept.begin(), s.kept.end());
      }
    }
  }
}

void CandidateSearch::find(int frameCount, const float* poses, const float* points,
                           CandidateTable& table, const std::uint8_t* active) const {
  checkChunk("closest triangle", frameCount, poses != nullptr && points != nullptr);
  checkFinite("closest triangle", "driver vertex", frameCount, mVertexCount, poses);
  checkFinite("closest triangle", "driven point", frameCount, mPointCount, points);

  const std::size_t poseStride = 3 * static_cast<std::size_t>(mVertexCount);
  const std::size_t pointStride = 3 * static_cast<std::size_t>(mPointCount);
  std::vector<FrameCandidates> frames(static_cast<std::size_t>(frameCount));
  parallelFor(frameCount, mThreads, [&](int f) {
    const float* pose = poses + static_cast<std::size_t>(f) * poseStride;
    const float* framePoints = points + static_cast<std::size_t>(f) * pointStride;
    const double scale =
        std::max(frameMagnitude(pose, mVertexCount), frameMagnitude(framePoints, mPointCount));
    findFrame(pose, framePoints,
              active == nullptr ? nullptr : active + static_cast<std::size_t>(f) * mPointCount,
              scale, frames[static_cast<std::size_t>(f)]);
  });

  const std::size_t items = static_cast<std::size_t>(frameCount) * mPointCount;
  table.start.resize(items + 1);
  std::vector<std::size_t> frameFirst(static_cast<std::size_t>(frameCount) + 1, 0);
  for (int f = 0; f < frameCount; ++f) {
    frameFirst[static_cast<std::size_t>(f) + 1] =
        frameFirst[static_cast<std::size_t>(f)] +
        frames[static_cast<std::size_t>(f)].triangles.size();
  }
  const std::size_t total = frameFirst.back();
  if (total > static_cast<std::size_t>(INT_MAX)) {
    DS_THROW(kInput, "closest triangle: ", total, " candidates in a chunk of ", frameCount,
             " frames exceed one launch; evaluate fewer frames per call");
  }
  table.triangles.resize(total);
  table.start[items] = static_cast<std::int32_t>(total);
  parallelFor(frameCount, mThreads, [&](int f) {
    const FrameCandidates& frame = frames[static_cast<std::size_t>(f)];
    std::size_t cursor = frameFirst[static_cast<std::size_t>(f)];
    const std::size_t firstItem = static_cast<std::size_t>(f) * mPointCount;
    for (int i = 0; i < mPointCount; ++i) {
      const std::size_t count = static_cast<std::size_t>(frame.count[static_cast<std::size_t>(i)]);
      const auto from = frame.triangles.begin() + frame.offset[static_cast<std::size_t>(i)];
      table.start[firstItem + static_cast<std::size_t>(i)] = static_cast<std::int32_t>(cursor);
      std::copy(from, from + static_cast<std::ptrdiff_t>(count),
                table.triangles.begin() + static_cast<std::ptrdiff_t>(cursor));
      cursor += count;
    }
  });
}

}  // namespace drivenshape::correction
