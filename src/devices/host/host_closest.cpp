// SPDX-License-Identifier: Apache-2.0
// The host reference of the correction stage: the same candidate lists as the OpenCL backend,
// then plain C++ in double for the exact choice (kernels/closest.cl) and the local-frame
// transfer and rebuild (kernels/transfer.cl), and the penetration resolution
// (kernels/resolve.cl), frames in parallel on host threads.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include "closest.h"
#include "parallel.h"

#include "candidates.h"
#include "host_certificate.h"
#include "surface_features.h"
#include "triangle_distance.h"

namespace drivenshape {
namespace {

using correction::loadPoint;

class HostClosest final : public ClosestBackend {
 public:
  explicit HostClosest(const ClosestOptions& options) : mSearch(options.threads) {}

  std::string name() const override { return "host"; }

  void setSurface(const Mesh& driver, const BindingMask& mask) override {
    mSearch.setSurface(driver, mask);
    mCertificate.setSurface(driver, mask, mSearch.sceneScale());
    mFeatures = correction::buildFeatureTables(mSearch.triangles().data(), mSearch.triangleCount(),
                                               mSearch.vertexCount());
    mInside = std::make_unique<InsideAudit>(driver);
    mSides.clear();
  }

  void setExitFade(float fade) override {
    correction::checkExitFade(fade);
    mFade = fade;
  }

  void setSides(const std::vector<std::int8_t>& sides) override {
    correction::checkSides(sides, mSearch.pointCount());
    mSides = sides;
  }

  void countInside(int frameCount, DeviceArray& poses, DeviceArray& hits, DeviceArray& points,
                   int* inside) override {
    mSearch.checkChunk("inside count", frameCount, inside != nullptr && mInside != nullptr);
    mInside->countInsideFrames(frameCount, poses.read<float>(), mSearch.pointCount(),
                               points.read<float>(), hits.read<SurfaceHit>(), inside,
                               mSearch.threads(), mSides.empty() ? nullptr : mSides.data());
  }

  void closest(int frameCount, const float* poses, const float* points, SurfaceHit* hits) override {
    mSearch.checkChunk("closest triangle", frameCount, hits != nullptr);
    exact(frameCount, poses, points, hits, nullptr);
  }

  void closestOrClearBlock(int frameCount, DeviceArray& poses, DeviceArray& points, float clearance,
                           DeviceArray& hits, int* cleared, DeviceArray* answered,
                           bool keep) override {
    mSearch.checkChunk("closest triangle", frameCount, true);
    correction::checkOffset(clearance);
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
    mCertificate.clear(frameCount, posesIn, pointsIn, clearance, out, mActive.data(),
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

 private:
  /// The exact closest triangle of every item (of those flagged in `active`, F x Vd, when
  /// given; the others' hits stay as they are).
  void exact(int frameCount, const float* poses, const float* points, SurfaceHit* hits,
             const std::uint8_t* active) {
    if (active != nullptr &&
        std::none_of(active, active + static_cast<std::size_t>(frameCount) * mSearch.pointCount(),
                     [](std::uint8_t a) { return a != 0; })) {
      return;
    }
    mSearch.find(frameCount, poses, points, mCandidates, active);
    const int pointCount = mSearch.pointCount();
    const std::size_t poseStride = 3 * static_cast<std::size_t>(mSearch.vertexCount());
    const double tieRelative = DS_TIE_RELATIVE_DOUBLE;
    const double tieAbsolute = static_cast<double>(
        static_cast<float>(DS_TIE_SCALE2_DOUBLE * mSearch.sceneScale() * mSearch.sceneScale()));
    const std::int32_t* triangles = mSearch.triangles().data();
    parallelFor(frameCount, mSearch.threads(), [&](int f) {
      const float* pose = poses + static_cast<std::size_t>(f) * poseStride;
      for (int i = 0; i < pointCount; ++i) {
        const std::size_t item = static_cast<std::size_t>(f) * pointCount + i;
        if (active != nullptr && active[item] == 0) {
          continue;
        }
        const Eigen::Vector3d p = loadPoint(points, static_cast<long>(item));
        const int first = mCandidates.start[item];
        const int last = mCandidates.start[item + 1];
        auto distance2 = [&](int t, double& u, double& v) {
          const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(t);
          return correction::triangleDistance2(p, loadPoint(pose, tri[0]), loadPoint(pose, tri[1]),
                                               loadPoint(pose, tri[2]), u, v);
        };
        double u = 0.0;
        double v = 0.0;
        double best = std::numeric_limits<double>::infinity();
        for (int k = first; k < last; ++k) {
          best =
              std::fmin(best, distance2(mCandidates.triangles[static_cast<std::size_t>(k)], u, v));
        }
        // Same float-rounded tie parameters as the kernel's DsClosestParams.
        const double band =
            best + static_cast<double>(static_cast<float>(tieRelative)) * best + tieAbsolute;
        SurfaceHit hit;
        hit.distance2 = static_cast<float>(best);
        for (int k = first; k < last; ++k) {
          const int t = mCandidates.triangles[static_cast<std::size_t>(k)];
          const double d2 = distance2(t, u, v);
          if (d2 <= band) {
            hit.triangle = t;
            hit.u = static_cast<float>(u);
            hit.v = static_cast<float>(v);
            hit.distance2 = static_cast<float>(d2);
            break;
          }
        }
        hits[item] = hit;
      }
    });
  }

 public:
  void transfer(int frameCount, const SurfaceHit* hits, const float* fromPoses,
                const float* toPoses, const float* points, float* out) override {
    correction::checkTransfer(mSearch, frameCount, hits, fromPoses, toPoses, points, out);
    const int pointCount = mSearch.pointCount();
    const std::size_t poseStride = 3 * static_cast<std::size_t>(mSearch.vertexCount());
    const std::int32_t* triangles = mSearch.triangles().data();
    parallelFor(frameCount, mSearch.threads(), [&](int f) {
      const float* from = fromPoses + static_cast<std::size_t>(f) * poseStride;
      const float* to = toPoses + static_cast<std::size_t>(f) * poseStride;
      for (int i = 0; i < pointCount; ++i) {
        const std::size_t item = static_cast<std::size_t>(f) * pointCount + i;
        const SurfaceHit& hit = hits[item];
        const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(hit.triangle);
        const double u = hit.u;
        const double v = hit.v;
        correction::LocalFrame f0;
        correction::LocalFrame f1;
        const bool ok0 = correction::localFrame(loadPoint(from, tri[0]), loadPoint(from, tri[1]),
                                                loadPoint(from, tri[2]), u, v, f0);
        const bool ok1 = correction::localFrame(loadPoint(to, tri[0]), loadPoint(to, tri[1]),
                                                loadPoint(to, tri[2]), u, v, f1);
        const Eigen::Vector3d d = loadPoint(points, static_cast<long>(item)) - f0.q;
        const Eigen::Vector3d result =
            ok0 && ok1 ? Eigen::Vector3d(f1.q + d.dot(f0.e1) * f1.e1 + d.dot(f0.e2) * f1.e2 +
                                         d.dot(f0.n) * f1.n)
                       : Eigen::Vector3d(f1.q + d);
        for (int a = 0; a < 3; ++a) {
          out[3 * item + static_cast<std::size_t>(a)] = static_cast<float>(result[a]);
        }
      }
    });
  }

  void rebuild(int frameCount, const SurfaceHit* hits, const float* toPoses, const float* local,
               float* out) override {
    correction::checkRebuild(mSearch, frameCount, hits, toPoses, local, out);
    const int pointCount = mSearch.pointCount();
    const std::size_t poseStride = 3 * static_cast<std::size_t>(mSearch.vertexCount());
    const std::int32_t* triangles = mSearch.triangles().data();
    parallelFor(frameCount, mSearch.threads(), [&](int f) {
      const float* to = toPoses + static_cast<std::size_t>(f) * poseStride;
      for (int i = 0; i < pointCount; ++i) {
        const std::size_t item = static_cast<std::size_t>(f) * pointCount + i;
        const SurfaceHit& hit = hits[i];
        const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(hit.triangle);
        correction::LocalFrame frame;
        const bool ok = correction::localFrame(loadPoint(to, tri[0]), loadPoint(to, tri[1]),
                                               loadPoint(to, tri[2]), hit.u, hit.v, frame);
        const Eigen::Vector3d l = loadPoint(local, static_cast<long>(item));
        const Eigen::Vector3d result =
            ok ? Eigen::Vector3d(frame.q + l.x() * frame.e1 + l.y() * frame.e2 + l.z() * frame.n)
               : Eigen::Vector3d(frame.q + l);
        for (int a = 0; a < 3; ++a) {
          out[3 * item + static_cast<std::size_t>(a)] = static_cast<float>(result[a]);
        }
      }
    });
  }

  void resolve(int frameCount, const float* poses, const SurfaceHit* hits, float offset,
               float* points, int* moved) override {
    correction::checkResolve(mSearch, frameCount, poses, hits, offset, points);
    const int pointCount = mSearch.pointCount();
    const std::size_t poseStride = 3 * static_cast<std::size_t>(mSearch.vertexCount());
    const std::int32_t* triangles = mSearch.triangles().data();
    const correction::FeatureView features = correction::viewOf(mFeatures);
    parallelFor(frameCount, mSearch.threads(), [&](int f) {
      const float* pose = poses + static_cast<std::size_t>(f) * poseStride;
      std::vector<float> boxes;  // exitFraction()'s, of this frame
      int count = 0;
      for (int i = 0; i < pointCount; ++i) {
        const std::size_t item = static_cast<std::size_t>(f) * pointCount + i;
        const SurfaceHit& hit = hits[item];
        const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(hit.triangle);
        const Eigen::Vector3d a = loadPoint(pose, tri[0]);
        const double u = hit.u;
        const double v = hit.v;
        const Eigen::Vector3d q =
            a + u * (loadPoint(pose, tri[1]) - a) + v * (loadPoint(pose, tri[2]) - a);
        const Eigen::Vector3d p = loadPoint(points, static_cast<long>(item));
        const Eigen::Vector3d offsetVector = p - q;
        const Eigen::Vector3d normal =
            correction::pseudoNormal(pose, triangles, features, hit.triangle, u, v);
        const double distance = offsetVector.norm();
        const double signedDistance = offsetVector.dot(normal) < 0.0 ? -distance : distance;
        const double length = normal.norm();
        // Inside points mirror outside ones: the offset surface under the skin is at -offset.
        const bool inside = !mSides.empty() && mSides[static_cast<std::size_t>(i)] == kSideInside;
        const double target = inside ? -static_cast<double>(offset) : static_cast<double>(offset);
        if (length > 0.0 && (inside ? signedDistance > target : signedDistance < target)) {
          const bool wrongSide = inside ? signedDistance > 0.0 : signedDistance < 0.0;
          const double fraction =
              mFade > 0.0f && wrongSide ? exitFraction(pose, p, q, distance, boxes) : 1.0;
          if (fraction > 0.0) {
            const Eigen::Vector3d full = q + (target / length) * normal;
            const Eigen::Vector3d result = fraction < 1.0 ? p + fraction * (full - p) : full;
            for (int k = 0; k < 3; ++k) {
              points[3 * item + static_cast<std::size_t>(k)] = static_cast<float>(result[k]);
            }
            ++count;
          }
        }
      }
      if (moved != nullptr) {
        moved[f] = count;
      }
    });
  }

 private:
  /// setExitFade()'s fraction of the move for a point p at depth `depth` from its closest point
  /// q on `pose`: the nearest other exit by brute force over every triangle. Only exits nearer
  /// than (1 + fade) depth change the fraction, so triangles whose box (`boxes`: min xyz, max
  /// xyz per triangle of this pose, filled on the first call) is farther are skipped.
  double exitFraction(const float* pose, const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                      double depth, std::vector<float>& boxes) const {
    if (depth <= 0.0) {
      return 1.0;
    }
    const std::int32_t* triangles = mSearch.triangles().data();
    const int triangleCount = mSearch.triangleCount();
    if (boxes.empty()) {
      boxes.resize(6 * static_cast<std::size_t>(triangleCount));
      for (int t = 0; t < triangleCount; ++t) {
        float* box = boxes.data() + 6 * static_cast<std::size_t>(t);
        for (int k = 0; k < 3; ++k) {
          const float* corner[3] = {pose + 3 * static_cast<std::size_t>(triangles[3 * t]),
                                    pose + 3 * static_cast<std::size_t>(triangles[3 * t + 1]),
                                    pose + 3 * static_cast<std::size_t>(triangles[3 * t + 2])};
          box[k] = std::min({corner[0][k], corner[1][k], corner[2][k]});
          box[3 + k] = std::max({corner[0][k], corner[1][k], corner[2][k]});
        }
      }
    }
    double other = (1.0 + mFade) * depth;  // beyond it the fraction is 1 anyway
    for (int t = 0; t < triangleCount; ++t) {
      const float* box = boxes.data() + 6 * static_cast<std::size_t>(t);
      double outside2 = 0.0;
      for (int k = 0; k < 3; ++k) {
        const double e = std::max(
            {static_cast<double>(box[k]) - p[k], 0.0, p[k] - static_cast<double>(box[3 + k])});
        outside2 += e * e;
      }
      if (outside2 >= other * other) {
        continue;
      }
      const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(t);
      const Eigen::Vector3d a = loadPoint(pose, tri[0]);
      const Eigen::Vector3d b = loadPoint(pose, tri[1]);
      const Eigen::Vector3d c = loadPoint(pose, tri[2]);
      double u = 0.0;
      double v = 0.0;
      const double d2 = correction::triangleDistance2(p, a, b, c, u, v);
      if (d2 < other * other && (a + u * (b - a) + v * (c - a) - q).squaredNorm() > depth * depth) {
        other = std::sqrt(d2);
      }
    }
    return std::min(std::max((other - depth) / (mFade * depth), 0.0), 1.0);
  }

  correction::CandidateSearch mSearch;
  correction::FeatureTables mFeatures;
  correction::CandidateTable mCandidates;
  correction::HostCertificate mCertificate;
  std::vector<std::uint8_t> mActive;
  std::vector<int> mCleared;
  std::unique_ptr<InsideAudit> mInside;
  std::vector<std::int8_t> mSides;  ///< Vd, or empty: every point outside
  float mFade = 0.0f;               ///< setExitFade()
};

}  // namespace

std::unique_ptr<ClosestBackend> makeHostClosest(const ClosestOptions& options) {
  return std::make_unique<HostClosest>(options);
}

}  // namespace drivenshape
