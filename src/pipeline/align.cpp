// SPDX-License-Identifier: Apache-2.0
#include "align.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numeric>

#include <drivenshape/error.h>

#include "parallel.h"

namespace drivenshape {

void RigidTransform::apply(const float* in, int count, float* out) const {
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d p(in[3 * i], in[3 * i + 1], in[3 * i + 2]);
    const Eigen::Vector3d q = rotation * p + translation;
    for (int a = 0; a < 3; ++a) {
      out[3 * i + a] = static_cast<float>(q(a));
    }
  }
}

void RigidTransform::applyInverse(const float* in, int count, float* out) const {
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d p(in[3 * i], in[3 * i + 1], in[3 * i + 2]);
    const Eigen::Vector3d q = rotation.transpose() * (p - translation);
    for (int a = 0; a < 3; ++a) {
      out[3 * i + a] = static_cast<float>(q(a));
    }
  }
}

std::vector<double> lumpedVertexAreas(const Mesh& mesh, const float* positions) {
  std::vector<double> areas(static_cast<std::size_t>(mesh.vertexCount()), 0.0);
  for (int t = 0; t < mesh.triangleCount(); ++t) {
    Eigen::Vector3d corner[3];
    for (int c = 0; c < 3; ++c) {
      const float* p = positions + 3 * mesh.triangles(t, c);
      corner[c] = Eigen::Vector3d(p[0], p[1], p[2]);
    }
    const double third = (corner[1] - corner[0]).cross(corner[2] - corner[0]).norm() / 6.0;
    for (int c = 0; c < 3; ++c) {
      areas[mesh.triangles(t, c)] += third;
    }
  }
  return areas;
}

namespace {

/// Whether the points (n x 3) with these weights span a plane: the second singular value of
/// their weighted covariance is not negligible.
bool spansPlane(const Eigen::Matrix<double, Eigen::Dynamic, 3>& points,
                const std::vector<double>& weights) {
  double total = 0.0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (int i = 0; i < static_cast<int>(weights.size()); ++i) {
    total += weights[i];
    centroid += weights[i] * points.row(i).transpose();
  }
  if (!(total > 0.0)) {
    return false;
  }
  centroid /= total;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (int i = 0; i < static_cast<int>(weights.size()); ++i) {
    const Eigen::Vector3d d = points.row(i).transpose() - centroid;
    covariance += (weights[i] / total) * d * d.transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(covariance);
  const Eigen::Vector3d s = svd.singularValues();
  return s(0) > 0.0 && s(1) > 1e-10 * s(0);
}

}  // namespace

RigidAligner::RigidAligner(const Mesh& mesh, const float* reference, std::vector<int> vertices,
                           const std::string& source)
    : mSource(source), mVertexCount(mesh.vertexCount()), mVertices(std::move(vertices)) {
  const int n = static_cast<int>(mVertices.size());
  if (n < 3) {
    DS_THROW(kInput, source,
             ": a rigid fit needs at least 3 non-collinear driver vertices, the "
             "selection has ",
             n, "; name a larger group or more indices");
  }
  const std::vector<double> areas = lumpedVertexAreas(mesh, reference);
  mAreas.resize(static_cast<std::size_t>(n));
  double total = 0.0;
  for (int i = 0; i < n; ++i) {
    mAreas[i] = areas[mVertices[i]];
    total += mAreas[i];
  }
  for (int i = 0; i < n; ++i) {
    // A selection without area (isolated vertices) falls back to uniform weights.
    mAreas[i] = total > 0.0 ? mAreas[i] / total : 1.0 / n;
  }
  // The reference points relative to their area centroid (keeps the sums below well scaled).
  mReference.resize(n, 3);
  for (int i = 0; i < n; ++i) {
    const float* p = reference + 3 * mVertices[i];
    mReference.row(i) = Eigen::RowVector3d(p[0], p[1], p[2]);
    mReferenceCentroid += mAreas[i] * mReference.row(i).transpose();
  }
  mReference.rowwise() -= mReferenceCentroid.transpose();
  setWeights(mAreas);
}

void RigidAligner::setWeights(std::vector<double> weights) {
  // A collinear (or single-point) weighted selection leaves the rotation about that line free.
  if (!spansPlane(mReference, weights)) {
    DS_THROW(kInput, mSource, ": the ", mVertices.size(),
             " selected driver vertices are (nearly) collinear at rest, so a rigid fit is not "
             "determined; select at least 3 vertices that span a plane");
  }
  const double total = std::accumulate(weights.begin(), weights.end(), 0.0);
  for (double& w : weights) {
    w /= total;
  }
  mWeights = std::move(weights);
}

RigidTransform RigidAligner::fitWith(const std::vector<double>& weights, const float* frame) const {
  const int n = static_cast<int>(mVertices.size());
  double total = 0.0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Vector3d referenceCentroid = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    if (weights[i] == 0.0) {
      continue;
    }
    const float* p = frame + 3 * mVertices[i];
    total += weights[i];
    centroid += weights[i] * Eigen::Vector3d(p[0], p[1], p[2]);
    referenceCentroid += weights[i] * mReference.row(i).transpose();
  }
  centroid /= total;
  referenceCentroid /= total;
  // H = sum_i w_i (x_i - cx) r_i^T (the reference centring cancels: sum_i w_i (x_i - cx) = 0);
  // R = V diag(1, 1, det(V U^T)) U^T.
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (int i = 0; i < n; ++i) {
    if (weights[i] == 0.0) {
      continue;
    }
    const float* p = frame + 3 * mVertices[i];
    const Eigen::Vector3d x = Eigen::Vector3d(p[0], p[1], p[2]) - centroid;
    h += weights[i] * x * (mReference.row(i) - referenceCentroid.transpose());
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d u = svd.matrixU();
  const Eigen::Matrix3d v = svd.matrixV();
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (v * u.transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  RigidTransform transform;
  transform.rotation = v * d * u.transpose();
  transform.translation = mReferenceCentroid + referenceCentroid - transform.rotation * centroid;
  return transform;
}

RigidTransform RigidAligner::fit(const float* frame) const {
  return fitWith(mWeights, frame);
}

void RigidAligner::weightByRigidity(const float* examples, int exampleCount,
                                    const RigidityOptions& options) {
  const int n = static_cast<int>(mVertices.size());
  if (exampleCount <= 0 || examples == nullptr) {
    return;
  }
  if (!(options.residualScale > 0.0) || !(options.seedRadius > 0.0) || options.seedCount < 0 ||
      options.iterations < 0) {
    DS_THROW(kInput, mSource,
             ": rigidity weighting needs a positive residual scale and seed radius and "
             "non-negative seed and iteration counts");
  }
  const Eigen::Vector3d low = mReference.colwise().minCoeff().transpose();
  const Eigen::Vector3d high = mReference.colwise().maxCoeff().transpose();
  const double diagonal = (high - low).norm();
  const double tau2 = std::pow(options.residualScale * diagonal, 2);
  // Mean over the examples of each selected vertex's squared residual under `weights`. The
  // examples are fitted in parallel; their residuals are summed in example order, so the result
  // does not depend on the thread count.
  std::vector<double> perExample(static_cast<std::size_t>(exampleCount) * n);
  auto residuals = [&](const std::vector<double>& weights) {
    parallelFor(exampleCount, options.threads, [&](int e) {
      const float* frame = examples + static_cast<std::size_t>(e) * mVertexCount * 3;
      const RigidTransform motion = fitWith(weights, frame);
      double* out = &perExample[static_cast<std::size_t>(e) * n];
      for (int i = 0; i < n; ++i) {
        const float* p = frame + 3 * mVertices[i];
        const Eigen::Vector3d q = motion.rotation * Eigen::Vector3d(p[0], p[1], p[2]) +
                                  motion.translation - mReferenceCentroid;
        out[i] = (q - mReference.row(i).transpose()).squaredNorm();
      }
    });
    std::vector<double> r2(static_cast<std::size_t>(n), 0.0);
    for (int e = 0; e < exampleCount; ++e) {
      const double* values = &perExample[static_cast<std::size_t>(e) * n];
      for (int i = 0; i < n; ++i) {
        r2[i] += values[i];
      }
    }
    for (double& value : r2) {
      value /= exampleCount;
    }
    return r2;
  };
  auto score = [&](const std::vector<double>& r2) {
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      sum += mAreas[i] * tau2 / (r2[i] + tau2);
    }
    return sum;
  };
  // 1. Seeds: the whole selection, then balls around evenly spaced selected vertices.
  std::vector<double> bestResiduals = residuals(mAreas);
  double bestScore = score(bestResiduals);
  const double radius2 = std::pow(options.seedRadius * diagonal, 2);
  const int seeds = std::min(options.seedCount, n);
  for (int s = 0; s < seeds; ++s) {
    const int centre = static_cast<int>(static_cast<long long>(s) * n / seeds);
    std::vector<double> ball(static_cast<std::size_t>(n), 0.0);
    for (int i = 0; i < n; ++i) {
      if ((mReference.row(i) - mReference.row(centre)).squaredNorm() <= radius2) {
        ball[i] = mAreas[i];
      }
    }
    if (!spansPlane(mReference, ball)) {
      continue;
    }
    std::vector<double> r2 = residuals(ball);
    const double value = score(r2);
    if (value > bestScore) {
      bestScore = value;
      bestResiduals = std::move(r2);
    }
  }
  // 2. Reweighting passes.
  std::vector<double> weights(static_cast<std::size_t>(n));
  auto reweight = [&](const std::vector<double>& r2) {
    for (int i = 0; i < n; ++i) {
      weights[i] = mAreas[i] / (r2[i] + tau2);
    }
  };
  reweight(bestResiduals);
  for (int pass = 0; pass < options.iterations; ++pass) {
    reweight(residuals(weights));
  }
  setWeights(weights);
}

}  // namespace drivenshape
