// SPDX-License-Identifier: Apache-2.0
// The pose model (drivenshape/pose_model.h): rigid parts of the driver, pose features, the
// kernel ridge regression of the local-frame offsets and its error predictor.

#include <drivenshape/pose_model.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <ostream>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include <drivenshape/error.h>

#include "local_encoding.h"
#include "parallel.h"
#include "pose_kernel.h"

namespace drivenshape {
namespace {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

Vector3d point(const float* xyz, int v) {
  return Vector3d(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]);
}

/// The rotation R (and translations) of the best rigid fit y ~ R (x - cx) + cy of a part:
/// `centered` holds the part's rest points minus their centroid.
Matrix3d fitRotation(const Eigen::Matrix3Xd& centered, const std::vector<int>& vertices,
                     const float* frame, Vector3d* center) {
  Vector3d cy = Vector3d::Zero();
  for (int v : vertices) {
    cy += point(frame, v);
  }
  cy /= static_cast<double>(vertices.size());
  Matrix3d h = Matrix3d::Zero();
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    h += centered.col(static_cast<Eigen::Index>(i)) * (point(frame, vertices[i]) - cy).transpose();
  }
  const Eigen::JacobiSVD<Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Matrix3d fix = Matrix3d::Identity();
  fix(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  if (center != nullptr) {
    *center = cy;
  }
  return svd.matrixV() * fix * svd.matrixU().transpose();
}

struct PartGeometry {
  std::vector<std::vector<int>> vertices;
  std::vector<Vector3d> centers;
  std::vector<Eigen::Matrix3Xd> centered;
};

PartGeometry partGeometry(const float* rest, const std::vector<int>& partOf, int parts) {
  PartGeometry g;
  g.vertices.resize(static_cast<std::size_t>(parts));
  for (std::size_t v = 0; v < partOf.size(); ++v) {
    g.vertices[static_cast<std::size_t>(partOf[v])].push_back(static_cast<int>(v));
  }
  for (int p = 0; p < parts; ++p) {
    const std::vector<int>& vs = g.vertices[static_cast<std::size_t>(p)];
    Vector3d c = Vector3d::Zero();
    for (int v : vs) {
      c += point(rest, v);
    }
    c /= std::max<double>(1.0, static_cast<double>(vs.size()));
    Eigen::Matrix3Xd x(3, static_cast<Eigen::Index>(vs.size()));
    for (std::size_t i = 0; i < vs.size(); ++i) {
      x.col(static_cast<Eigen::Index>(i)) = point(rest, vs[i]) - c;
    }
    g.centers.push_back(c);
    g.centered.push_back(std::move(x));
  }
  return g;
}

/// Assigns every vertex to the part whose rigid motions over `sample` frames explain it best;
/// returns the total squared residual.
double assignParts(const float* rest, int vertexCount, const float* frames,
                   const std::vector<int>& sample, int parts, std::vector<int>& partOf,
                   int threads) {
  const PartGeometry g = partGeometry(rest, partOf, parts);
  const std::size_t values = static_cast<std::size_t>(vertexCount) * 3;
  MatrixXd cost = MatrixXd::Zero(vertexCount, parts);
  parallelFor(parts, threads, [&](int p) {
    if (g.vertices[static_cast<std::size_t>(p)].size() < 3) {
      cost.col(p).setConstant(std::numeric_limits<double>::infinity());
      return;
    }
    for (int f : sample) {
      const float* frame = frames + static_cast<std::size_t>(f) * values;
      Vector3d cy;
      const Matrix3d r = fitRotation(g.centered[static_cast<std::size_t>(p)],
                                     g.vertices[static_cast<std::size_t>(p)], frame, &cy);
      for (int v = 0; v < vertexCount; ++v) {
        cost(v, p) +=
            (r * (point(rest, v) - g.centers[static_cast<std::size_t>(p)]) + cy - point(frame, v))
                .squaredNorm();
      }
    }
  });
  double total = 0.0;
  for (int v = 0; v < vertexCount; ++v) {
    Eigen::Index best = 0;
    total += cost.row(v).minCoeff(&best);
    partOf[static_cast<std::size_t>(v)] = static_cast<int>(best);
  }
  return total;
}

/// Renumbers parts 0..n-1 in order of first vertex, dropping empty ones; returns n.
int compactParts(std::vector<int>& partOf) {
  std::vector<int> map;
  for (int& p : partOf) {
    if (p >= static_cast<int>(map.size())) {
      map.resize(static_cast<std::size_t>(p) + 1, -1);
    }
    if (map[static_cast<std::size_t>(p)] < 0) {
      map[static_cast<std::size_t>(p)] =
          static_cast<int>(std::count_if(map.begin(), map.end(), [](int m) { return m >= 0; }));
    }
    p = map[static_cast<std::size_t>(p)];
  }
  return static_cast<int>(std::count_if(map.begin(), map.end(), [](int m) { return m >= 0; }));
}

/// Hard rigid clustering with `parts` farthest-point seeds; returns the residual.
double clusterParts(const Mesh& driver, const float* frames, int frameCount, int parts,
                    std::vector<int>& partOf, int threads) {
  const int vertexCount = driver.vertexCount();
  const float* rest = driver.positions.data();
  std::vector<int> seeds = {0};
  std::vector<double> distance(static_cast<std::size_t>(vertexCount));
  for (int v = 0; v < vertexCount; ++v) {
    distance[v] = (point(rest, v) - point(rest, 0)).squaredNorm();
  }
  while (static_cast<int>(seeds.size()) < parts) {
    const int next =
        static_cast<int>(std::max_element(distance.begin(), distance.end()) - distance.begin());
    seeds.push_back(next);
    for (int v = 0; v < vertexCount; ++v) {
      distance[v] = std::min(distance[v], (point(rest, v) - point(rest, next)).squaredNorm());
    }
  }
  partOf.assign(static_cast<std::size_t>(vertexCount), 0);
  for (int v = 0; v < vertexCount; ++v) {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t s = 0; s < seeds.size(); ++s) {
      const double d = (point(rest, v) - point(rest, seeds[s])).squaredNorm();
      if (d < best) {
        best = d;
        partOf[static_cast<std::size_t>(v)] = static_cast<int>(s);
      }
    }
  }
  std::vector<int> sample;
  const int step = std::max(1, frameCount / 80);
  for (int f = 0; f < frameCount; f += step) {
    sample.push_back(f);
  }
  double residual = 0.0;
  for (int iteration = 0; iteration < 12; ++iteration) {
    const std::vector<int> before = partOf;
    residual = assignParts(rest, vertexCount, frames, sample, parts, partOf, threads);
    if (partOf == before) {
      break;
    }
  }
  compactParts(partOf);
  return residual;
}

/// The tree of parts: the root rotates least over the clip; the others hang off the
/// neighbour (shared mesh edges) they share most edges with, grown from the root.
std::vector<int> partTree(const Mesh& driver, const float* frames, int frameCount,
                          const std::vector<int>& partOf, int parts) {
  const float* rest = driver.positions.data();
  const PartGeometry g = partGeometry(rest, partOf, parts);
  const std::size_t values = static_cast<std::size_t>(driver.vertexCount()) * 3;
  std::vector<double> angle(static_cast<std::size_t>(parts), 0.0);
  for (int p = 0; p < parts; ++p) {
    for (int f = 0; f < frameCount; ++f) {
      const Matrix3d r = fitRotation(g.centered[p], g.vertices[p],
                                     frames + static_cast<std::size_t>(f) * values, nullptr);
      angle[p] += std::acos(std::clamp((r.trace() - 1.0) / 2.0, -1.0, 1.0));
    }
  }
  MatrixXd shared = MatrixXd::Zero(parts, parts);
  for (int t = 0; t < driver.triangleCount(); ++t) {
    for (int e = 0; e < 3; ++e) {
      const int a = partOf[static_cast<std::size_t>(driver.triangles(t, e))];
      const int b = partOf[static_cast<std::size_t>(driver.triangles(t, (e + 1) % 3))];
      if (a != b) {
        shared(a, b) += 1;
        shared(b, a) += 1;
      }
    }
  }
  std::vector<int> parent(static_cast<std::size_t>(parts), -2);
  const int root = static_cast<int>(std::min_element(angle.begin(), angle.end()) - angle.begin());
  parent[static_cast<std::size_t>(root)] = -1;
  for (int added = 1; added < parts; ++added) {
    int bestChild = -1, bestParent = root;
    double bestShared = -1.0;
    for (int a = 0; a < parts; ++a) {
      if (parent[a] == -2) {
        continue;
      }
      for (int b = 0; b < parts; ++b) {
        if (parent[b] == -2 && shared(a, b) > bestShared) {
          bestShared = shared(a, b);
          bestChild = b;
          bestParent = a;
        }
      }
    }
    parent[static_cast<std::size_t>(bestChild)] = bestParent;
  }
  return parent;
}

/// k(x, y) of the model's kernel on rows of two feature matrices.
MatrixXd kernelMatrix(const MatrixXd& a, const MatrixXd& b, double lengthScale,
                      double linearWeight) {
  const MatrixXd dot = a * b.transpose();
  const VectorXd aa = a.rowwise().squaredNorm();
  const VectorXd bb = b.rowwise().squaredNorm();
  MatrixXd k(a.rows(), b.rows());
  const double scale = 1.0 / (2.0 * lengthScale * lengthScale);
  for (Eigen::Index j = 0; j < b.rows(); ++j) {
    for (Eigen::Index i = 0; i < a.rows(); ++i) {
      const double d2 = std::max(0.0, aa[i] + bb[j] - 2.0 * dot(i, j));
      k(i, j) = linearWeight * dot(i, j) + std::exp(-d2 * scale);
    }
  }
  return k;
}

/// Mean vertex distance between rows of two T x 3Vd offset blocks given in PCA coordinates
/// `coords` (rows x r) of the basis `components` (r x 3Vd): per row, the mean over vertices.
VectorXd meanVertexError(const MatrixXd& predicted, const MatrixXd& truth,
                         const MatrixXd& components) {
  const MatrixXd diff = (predicted - truth) * components;  // rows x 3Vd
  VectorXd out(diff.rows());
  const Eigen::Index vertices = diff.cols() / 3;
  for (Eigen::Index r = 0; r < diff.rows(); ++r) {
    double sum = 0.0;
    for (Eigen::Index v = 0; v < vertices; ++v) {
      sum += diff.row(r).segment(3 * v, 3).norm();
    }
    out[r] = sum / static_cast<double>(vertices);
  }
  return out;
}

/// The per-clip mixture's shares (PoseModel::clipMixtureWeight): entry 0 the model over every
/// clip's, weight / its variance, then each clip model's, 1 / its variance, normalised to sum
/// to 1. Variances are floored at 1e-12 (a pose on a reference frame).
std::vector<double> mixtureShares(double weight, double variance,
                                  const std::vector<double>& clipVariances) {
  constexpr double kFloor = 1e-12;
  std::vector<double> share = {weight / std::max(kFloor, variance)};
  for (double v : clipVariances) {
    share.push_back(1.0 / std::max(kFloor, v));
  }
  const double total = std::accumulate(share.begin(), share.end(), 0.0);
  for (double& s : share) {
    s /= total;
  }
  return share;
}

}  // namespace

std::array<double, 2> fitErrorLine(const Eigen::Ref<const Eigen::VectorXd>& sigma,
                                   const Eigen::Ref<const Eigen::VectorXd>& error) {
  if (sigma.size() != error.size() || sigma.size() < 2) {
    DS_THROW(kInput,
             "fitting the error predictor needs as many deviations as errors, at least 2 (got ",
             sigma.size(), " and ", error.size(), ")");
  }
  // Two unknowns, non-negative: the unconstrained least squares when it is feasible, else the
  // better of the two one-coefficient fits (the minimum then lies on a boundary).
  const double n = static_cast<double>(sigma.size());
  const double s1 = sigma.sum(), s2 = sigma.squaredNorm(), e1 = error.sum(), se = sigma.dot(error);
  const double det = n * s2 - s1 * s1;
  if (det > 1e-12 * n * s2) {
    const double bias = (s2 * e1 - s1 * se) / det, scale = (n * se - s1 * e1) / det;
    if (bias >= 0.0 && scale >= 0.0) {
      return {bias, scale};
    }
  }
  const auto cost = [&](double bias, double scale) {
    return (error.array() - bias - scale * sigma.array()).square().sum();
  };
  const std::array<double, 2> biasOnly = {std::max(0.0, e1 / n), 0.0};
  const std::array<double, 2> scaleOnly = {0.0, s2 > 0.0 ? std::max(0.0, se / s2) : 0.0};
  return cost(scaleOnly[0], scaleOnly[1]) < cost(biasOnly[0], biasOnly[1]) ? scaleOnly : biasOnly;
}

double conformalMargin(const std::vector<double>& error, const std::vector<double>& predicted,
                       double level) {
  if (error.size() != predicted.size() || error.empty()) {
    DS_THROW(kInput,
             "calibrating the coverage verdict needs as many predicted errors as errors, "
             "at least 1 (got ",
             predicted.size(), " and ", error.size(), ")");
  }
  if (!(level > 0.0 && level < 1.0)) {
    DS_THROW(kInput, "the coverage verdict's level must be between 0 and 1 (got ", level, ")");
  }
  const std::size_t n = error.size();
  std::vector<double> residuals(n);
  for (std::size_t i = 0; i < n; ++i) {
    residuals[i] = error[i] - predicted[i];
  }
  std::sort(residuals.begin(), residuals.end());
  const auto rank = static_cast<std::size_t>(std::ceil(static_cast<double>(n + 1) * level));
  return std::max(0.0, residuals[std::min(n, std::max<std::size_t>(1, rank)) - 1]);
}

MatrixXd poseKernel(const MatrixXd& a, const MatrixXd& b, double lengthScale, double linearWeight) {
  return kernelMatrix(a, b, lengthScale, linearWeight);
}

std::vector<int> referenceClipOffsets(const std::vector<std::array<int, 2>>& ranges,
                                      int historyNeeded) {
  constexpr std::int64_t kStep = 100000;
  std::vector<int> offsets;
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  for (const std::array<int, 2>& range : ranges) {
    std::int64_t offset = 0;
    if (!offsets.empty()) {
      // Smallest positive multiple of kStep with first + offset > last + historyNeeded + 1.
      const std::int64_t gap = last + historyNeeded + 2 - range[0];
      offset = std::max<std::int64_t>(1, (gap + kStep - 1) / kStep) * kStep;
    }
    if (range[1] + offset > std::numeric_limits<int>::max() / 2) {
      DS_THROW(kInput, "reference clip ", offsets.size() + 1, " (frames ", range[0], "-", range[1],
               ") cannot be numbered apart from the clips before it: its frame numbers are too "
               "large; renumber the caches from a smaller first frame");
    }
    offsets.push_back(static_cast<int>(offset));
    last = std::max(last, range[1] + offset);
  }
  return offsets;
}

std::vector<int> findRigidParts(const Mesh& driver, const float* frames, int frameCount, int parts,
                                std::vector<int>& parent, int threads, std::ostream* log) {
  if (frameCount < 2) {
    DS_THROW(kInput, "finding the driver's rigid parts needs at least 2 reference frames (got ",
             frameCount, ")");
  }
  std::vector<int> partOf;
  if (parts > 0) {
    clusterParts(driver, frames, frameCount, parts, partOf, threads);
  } else {
    // More parts while each count leaves at most two thirds of the residual of the count kept
    // before it. A count that does not (a poor split, e.g. a thigh cut across) gets one more
    // try: the next count is kept when it leaves at most a third (the limbs split at their
    // joints); otherwise the search stops.
    double residual = clusterParts(driver, frames, frameCount, 2, partOf, threads);
    int kept = 2;
    for (int count = 3; count <= 8; ++count) {
      std::vector<int> more;
      const double next = clusterParts(driver, frames, frameCount, count, more, threads);
      if (log != nullptr) {
        *log << "  rigid parts: " << count << " parts leave " << next / residual
             << " of the residual of " << kept << "\n";
      }
      const bool lookahead = count == kept + 2;
      if (next <= residual * (lookahead ? 1.0 / 3.0 : 2.0 / 3.0)) {
        residual = next;
        kept = count;
        partOf = std::move(more);
      } else if (lookahead) {
        break;
      }
    }
  }
  const int count = 1 + *std::max_element(partOf.begin(), partOf.end());
  parent = partTree(driver, frames, frameCount, partOf, count);
  return partOf;
}

PosePredictor::PosePredictor(const PoseModel& model, const Mesh& driver) : mModel(model) {
  const float* rest = driver.positions.data();
  PartGeometry g = partGeometry(rest, model.partOf, model.partCount());
  mPartVertices = std::move(g.vertices);
  mRestCenters = std::move(g.centers);
  mRestCentered = std::move(g.centered);
  mSiblingPairs = model.siblingPairs();
  mPoseFeatureCount = model.poseFeatureCount();
  mFeatureCount = model.featureCount();
  if (model.coefficients.empty()) {
    return;
  }
  const int t = model.frameCount(), d = model.featureCount(), r = model.rank();
  mFeatures =
      Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          model.features.data(), t, d)
          .cast<double>();
  mCoefficients =
      Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          model.coefficients.data(), r, t)
          .cast<double>();
  MatrixXd k = kernelMatrix(mFeatures, mFeatures, model.lengthScale, model.linearWeight);
  k.diagonal().array() += model.ridge;
  mKernelInverse = k.llt().solve(MatrixXd::Identity(t, t));
  if (model.clipMixtureWeight > 0.0) {
    const MatrixXd clipCoefficients =
        Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            model.clipCoefficients.data(), r, t)
            .cast<double>();
    int begin = 0;
    for (int count : model.clipSizes) {
      ClipModel clip;
      clip.begin = begin;
      clip.count = count;
      clip.kernelInverse =
          k.block(begin, begin, count, count).llt().solve(MatrixXd::Identity(count, count));
      clip.coefficients = clipCoefficients.middleCols(begin, count);
      mClipModels.push_back(std::move(clip));
      begin += count;
    }
  }
}

Eigen::MatrixXd PosePredictor::blockFeatures(const float* driverFrames,
                                             const std::vector<int>& frames,
                                             const EarlierFrames& history, int threads) const {
  const int count = static_cast<int>(frames.size());
  const int total = count + static_cast<int>(history.frames.size());
  const int n = mPoseFeatureCount, d = mFeatureCount;
  const std::size_t values = mModel.partOf.size() * 3;
  // The block: the wanted frames and the earlier ones by frame number (features() walks back
  // through consecutive numbers).
  std::vector<int> order(static_cast<std::size_t>(total));
  std::iota(order.begin(), order.end(), 0);
  const auto number = [&](int i) { return i < count ? frames[i] : history.frames[i - count]; };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return number(a) < number(b); });
  std::vector<int> numbers(static_cast<std::size_t>(total));
  std::vector<int> position(static_cast<std::size_t>(count));
  for (int k = 0; k < total; ++k) {
    numbers[k] = number(order[k]);
    if (order[k] < count) {
      position[order[k]] = k;
    }
  }
  std::vector<double> pose(static_cast<std::size_t>(total) * n);
  parallelFor(total, threads, [&](int k) {
    const int i = order[k];
    const float* frame =
        i < count ? driverFrames + i * values : history.driverFrames + (i - count) * values;
    poseFeatures(frame, &pose[static_cast<std::size_t>(k) * n]);
  });
  MatrixXd x(count, d);
  parallelFor(count, threads, [&](int i) {
    std::vector<double> row(static_cast<std::size_t>(d));
    features(pose.data(), numbers.data(), total, position[i], row.data());
    x.row(i) = Eigen::Map<const Eigen::RowVectorXd>(row.data(), d);
  });
  return x;
}

void PosePredictor::poseFeatures(const float* frame, double* out) const {
  const int parts = mModel.partCount();
  std::vector<Matrix3d> rotation(static_cast<std::size_t>(parts));
  for (int p = 0; p < parts; ++p) {
    rotation[p] = fitRotation(mRestCentered[p], mPartVertices[p], frame, nullptr);
  }
  const Vector3d up(mModel.up[0], mModel.up[1], mModel.up[2]);
  int o = 0;
  for (int p = 0; p < parts; ++p) {
    const int q = mModel.parent[static_cast<std::size_t>(p)];
    if (q < 0) {
      const Vector3d g = rotation[p].transpose() * up - up;
      for (int c = 0; c < 3; ++c) {
        out[o++] = g[c];
      }
    } else {
      const Matrix3d relative = rotation[q].transpose() * rotation[p] - Matrix3d::Identity();
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          out[o++] = relative(i, j);
        }
      }
    }
  }
  if (mModel.siblingWeight > 0.0) {
    for (const std::array<int, 2>& pair : mSiblingPairs) {
      const Matrix3d relative =
          rotation[pair[0]].transpose() * rotation[pair[1]] - Matrix3d::Identity();
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          out[o++] = mModel.siblingWeight * relative(i, j);
        }
      }
    }
  }
}

void PosePredictor::features(const double* pose, const int* frames, int count, int i,
                             double* out) const {
  const int n = mPoseFeatureCount;
  // earlier[j] = block index of frame frames[i] - j, the earliest found standing in.
  const int need = mModel.historyNeeded();
  std::vector<int> earlier(static_cast<std::size_t>(need) + 1, i);
  int found = i;
  for (int j = 1; j <= need; ++j) {
    if (found > 0 && found - 1 < count && frames[found - 1] == frames[i] - j) {
      --found;
    }
    earlier[static_cast<std::size_t>(j)] = found;
  }
  const double* now = pose + static_cast<std::size_t>(i) * n;
  std::copy_n(now, n, out);
  int o = n;
  if (mModel.velocityLag > 0) {
    const double* then = pose + static_cast<std::size_t>(earlier[mModel.velocityLag]) * n;
    for (int c = 0; c < n; ++c) {
      out[o++] = now[c] - then[c];
    }
  }
  if (mModel.historyFrames > 1) {
    for (int c = 0; c < n; ++c) {
      double sum = 0.0;
      for (int j = 0; j < mModel.historyFrames; ++j) {
        sum += pose[static_cast<std::size_t>(earlier[j]) * n + c];
      }
      out[o++] = now[c] - sum / mModel.historyFrames;
    }
  }
}

PosePredictor::Prediction PosePredictor::predict(const double* features) const {
  const int d = mFeatureCount;
  const Eigen::Map<const Eigen::RowVectorXd> x(features, d);
  const VectorXd k =
      kernelMatrix(x, mFeatures, mModel.lengthScale, mModel.linearWeight).transpose();
  Prediction p;
  p.weights = mCoefficients * k;
  const double prior = mModel.linearWeight * x.squaredNorm() + 1.0;
  p.sigma = std::sqrt(std::max(0.0, prior - k.dot(mKernelInverse * k)));
  if (!mClipModels.empty()) {
    std::vector<double> variances;
    std::vector<VectorXd> weights;
    for (const ClipModel& clip : mClipModels) {
      const auto kk = k.segment(clip.begin, clip.count);
      variances.push_back(prior - kk.dot(clip.kernelInverse * kk));
      weights.push_back(clip.coefficients * kk);
    }
    const std::vector<double> share =
        mixtureShares(mModel.clipMixtureWeight, p.sigma * p.sigma, variances);
    p.weights *= share[0];
    for (std::size_t c = 0; c < weights.size(); ++c) {
      p.weights += share[c + 1] * weights[c];
    }
  }
  p.predictedError = mModel.predictedError(p.sigma);
  return p;
}

namespace {

/// The model's rigid parts: the rig's (options.partOf) or those found from the clip's `t`
/// driver frames; each needs 3 vertices for its rotation.
void setRigidParts(PoseModel& model, const Mesh& driver, const float* driverFrames, int t,
                   const PoseModelOptions& options, int threads, std::ostream* log) {
  if (!options.partOf.empty()) {
    if (options.partOf.size() != static_cast<std::size_t>(driver.vertexCount())) {
      DS_THROW(kInput, "the rig's parts name ", options.partOf.size(),
               " driver vertices but the driver has ", driver.vertexCount());
    }
    model.partOf = options.partOf;
    model.parent = options.parentOf;
  } else {
    model.partOf =
        findRigidParts(driver, driverFrames, t, options.parts, model.parent, threads, log);
  }
  for (int p = 0; p < model.partCount(); ++p) {
    const auto size = std::count(model.partOf.begin(), model.partOf.end(), p);
    if (size < 3) {
      DS_THROW(kInput, "driver part ", p, " has ", size,
               " vertices; a part needs 3 for its rotation (fewer parts: --model-parts)");
    }
  }
  if (log != nullptr) {
    *log << "  pose model: " << model.partCount() << " rigid parts (parents";
    for (int p : model.parent) {
      *log << " " << p;
    }
    *log << ")\n";
  }
}

/// The regression targets, T x 3Vd: the local offsets of every reference frame minus the
/// rest offsets.
MatrixXd localOffsetTargets(const Mesh& driver, const Mesh& driven, const float* driverFrames,
                            const float* drivenFrames, int t,
                            const std::vector<SurfaceHit>& restHits) {
  const std::size_t dv = static_cast<std::size_t>(driver.vertexCount()) * 3;
  const std::size_t dd = static_cast<std::size_t>(driven.vertexCount()) * 3;
  std::vector<float> restLocal(dd), local(dd);
  encodeLocal(driver, driver.positions.data(), driven.vertexCount(), driven.positions.data(),
              restHits.data(), restLocal.data());
  MatrixXd y(t, static_cast<Eigen::Index>(dd));
  for (int f = 0; f < t; ++f) {
    encodeLocal(driver, driverFrames + f * dv, driven.vertexCount(), drivenFrames + f * dd,
                restHits.data(), local.data());
    for (std::size_t i = 0; i < dd; ++i) {
      y(f, static_cast<Eigen::Index>(i)) = static_cast<double>(local[i]) - restLocal[i];
    }
  }
  return y;
}

/// The principal components of the targets (those of eigenvalue above 1e-12 of the largest):
/// the regression runs on the T coordinates, the same squared error as on every vertex.
struct OffsetBasis {
  int rank = 0;
  MatrixXd components;  ///< rank x 3Vd
  MatrixXd coords;      ///< T x rank, the targets in the basis
};

OffsetBasis offsetBasis(const MatrixXd& y) {
  const int t = static_cast<int>(y.rows());
  const Eigen::SelfAdjointEigenSolver<MatrixXd> eig(y * y.transpose());
  std::vector<int> order(static_cast<std::size_t>(t));
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return eig.eigenvalues()[a] > eig.eigenvalues()[b]; });
  OffsetBasis basis;
  MatrixXd u(t, t), components(t, y.cols());
  for (int j = 0; j < t; ++j) {
    const double lambda = eig.eigenvalues()[order[j]];
    if (lambda <= 1e-12 * std::max(1e-300, eig.eigenvalues().maxCoeff())) {
      break;
    }
    u.col(basis.rank) = eig.eigenvectors().col(order[j]);
    components.row(basis.rank) =
        (y.transpose() * u.col(basis.rank)).transpose() / std::sqrt(lambda);
    ++basis.rank;
  }
  components.conservativeResize(basis.rank, components.cols());
  basis.coords = y * components.transpose();
  basis.components = std::move(components);
  return basis;
}

/// Hyper-parameters of the kernel ridge regression and their cross-validated squared error.
struct KernelFit {
  double lengthScale, linearWeight, ridge, error;
};

/// The median distance between the feature rows of two reference frames (at least 1e-9):
/// the unit of the length scales tried.
double medianFeatureDistance(const MatrixXd& x) {
  const int t = static_cast<int>(x.rows());
  std::vector<double> distances;
  for (int a = 0; a < t; ++a) {
    for (int b = a + 1; b < t; ++b) {
      distances.push_back((x.row(a) - x.row(b)).norm());
    }
  }
  std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
  return std::max(1e-9, distances[distances.size() / 2]);
}

/// Kernel ridge regression on the reference frames `train` (kernel `kAll` over every reference
/// frame, ridge `ridge`): writes the prediction of `coords` at the frames `test` into those rows
/// of `predicted` and their posterior variance into those entries of `variance`.
void predictFrom(const MatrixXd& kAll, const MatrixXd& coords, double ridge,
                 const std::vector<int>& train, const std::vector<int>& test, MatrixXd& predicted,
                 VectorXd& variance) {
  const auto n = static_cast<Eigen::Index>(train.size());
  const auto m = static_cast<Eigen::Index>(test.size());
  MatrixXd k(n, n), ks(m, n), yt(n, coords.cols());
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      k(i, j) = kAll(train[i], train[j]);
    }
    k(i, i) += ridge;
    yt.row(i) = coords.row(train[i]);
    for (Eigen::Index j = 0; j < m; ++j) {
      ks(j, i) = kAll(test[j], train[i]);
    }
  }
  const Eigen::LLT<MatrixXd> llt(k);
  const MatrixXd p = ks * llt.solve(yt);
  const MatrixXd v = llt.solve(ks.transpose());
  for (Eigen::Index j = 0; j < m; ++j) {
    predicted.row(test[j]) = p.row(j);
    variance[test[j]] = std::max(0.0, kAll(test[j], test[j]) - ks.row(j).dot(v.col(j)));
  }
}

/// Cross-validation on 5 contiguous blocks of the clip: the prediction (T x rank) and the
/// posterior deviation (T) of every reference frame by the fit `c` on the other blocks. Frames
/// in [leftBegin, leftEnd) (a clip left out; empty by default) are in no block's training set:
/// they are predicted by the fit on every frame outside the range instead.
void crossValidate(const MatrixXd& x, const MatrixXd& coords, const KernelFit& c,
                   MatrixXd& predicted, VectorXd& sigma, int leftBegin = 0, int leftEnd = 0) {
  const int t = static_cast<int>(x.rows());
  const int blocks = 5;
  const auto blockOf = [&](int f) { return std::min(blocks - 1, f * blocks / t); };
  const auto left = [&](int f) { return f >= leftBegin && f < leftEnd; };
  predicted.resize(t, coords.cols());
  sigma.resize(t);
  const MatrixXd kAll = kernelMatrix(x, x, c.lengthScale, c.linearWeight);
  for (int b = 0; b < blocks; ++b) {
    std::vector<int> train, test;
    for (int f = 0; f < t; ++f) {
      if (!left(f)) {
        (blockOf(f) == b ? test : train).push_back(f);
      }
    }
    predictFrom(kAll, coords, c.ridge, train, test, predicted, sigma);
  }
  if (leftEnd > leftBegin) {
    std::vector<int> train, test;
    for (int f = 0; f < t; ++f) {
      (left(f) ? test : train).push_back(f);
    }
    predictFrom(kAll, coords, c.ridge, train, test, predicted, sigma);
  }
  sigma = sigma.cwiseSqrt();
}

/// The hyper-parameters of the grid (length scales in units of the median feature distance,
/// linear weights, ridges) with the smallest cross-validated error.
KernelFit chooseKernel(const MatrixXd& x, const MatrixXd& coords, int threads) {
  const double median = medianFeatureDistance(x);
  std::vector<KernelFit> candidates;
  for (double ls : {0.25, 0.5, 1.0}) {
    for (double lw : {1.0, 3.0, 10.0}) {
      for (double ridge : {0.03, 0.1, 0.3, 1.0}) {
        candidates.push_back({ls * median, lw, ridge, 0.0});
      }
    }
  }
  parallelFor(static_cast<int>(candidates.size()), threads, [&](int i) {
    MatrixXd predicted;
    VectorXd sigma;
    crossValidate(x, coords, candidates[i], predicted, sigma);
    candidates[i].error = (predicted - coords).squaredNorm();
  });
  return *std::min_element(
      candidates.begin(), candidates.end(),
      [](const KernelFit& a, const KernelFit& b) { return a.error < b.error; });
}

/// The error predictor: the cross-validated mean vertex error of each frame against the
/// posterior deviation, least squares; also the mean errors of the fit and of the binding.
void fitErrorPredictor(PoseModel& model, const MatrixXd& x, const OffsetBasis& basis,
                       const KernelFit& best) {
  MatrixXd predicted;
  VectorXd sigma;
  crossValidate(x, basis.coords, best, predicted, sigma);
  const VectorXd error = meanVertexError(predicted, basis.coords, basis.components);
  const VectorXd bindingError =
      meanVertexError(MatrixXd::Zero(x.rows(), basis.rank), basis.coords, basis.components);
  model.crossValidationError = error.mean();
  model.bindingError = bindingError.mean();
  const std::array<double, 2> line = fitErrorLine(sigma, error);
  model.errorBias = line[0];
  model.errorScale = line[1];
  model.frameErrors.assign(error.data(), error.data() + error.size());
  model.frameSigmas.assign(sigma.data(), sigma.data() + sigma.size());
}

/// The reference frames' errors and deviations held out as the verdict is calibrated: with
/// their clip left out when there are several clips, else in the cross-validation.
const std::vector<double>& heldOutErrors(const PoseModel& model) {
  return model.leftOutErrors.empty() ? model.frameErrors : model.leftOutErrors;
}
const std::vector<double>& heldOutSigmas(const PoseModel& model) {
  return model.leftOutErrors.empty() ? model.frameSigmas : model.leftOutSigmas;
}

/// The verdict's margin at `level` (PoseModel::verdictMargin): over the frames' held-out errors
/// with their clip left out when there are several clips (a whole clip held out is what a new
/// shot is like), else over the cross-validation.
void calibrateVerdict(PoseModel& model, double level) {
  const std::vector<double>& errors = heldOutErrors(model);
  const std::vector<double>& sigmas = heldOutSigmas(model);
  std::vector<double> predictedErrors;
  for (double s : sigmas) {
    predictedErrors.push_back(model.predictedError(s));
  }
  model.verdictLevel = level;
  model.verdictMargin = conformalMargin(errors, predictedErrors, level);
}

/// What each reference clip adds (PoseModel::clipErrors): the cross-validation again with each
/// clip left out in turn, the kernel settings kept; also every frame's error and deviation
/// when its clip was left out (PoseModel::leftOutErrors, leftOutSigmas).
std::vector<ClipContribution> clipContributions(PoseModel& model, const MatrixXd& x,
                                                const OffsetBasis& basis, const KernelFit& best,
                                                const std::vector<int>& clipSizes, int threads) {
  const std::size_t clips = clipSizes.size();
  std::vector<int> start = {0};
  for (int size : clipSizes) {
    start.push_back(start.back() + size);
  }
  const auto clipMeans = [&](const VectorXd& error) {
    std::vector<double> means;
    for (std::size_t k = 0; k < clips; ++k) {
      means.push_back(error.segment(start[k], clipSizes[k]).mean());
    }
    return means;
  };
  const std::vector<double> withAll =
      clipMeans(Eigen::Map<const VectorXd>(model.frameErrors.data(), x.rows()));
  std::vector<ClipContribution> out(clips);
  model.leftOutErrors.assign(static_cast<std::size_t>(x.rows()), 0.0);
  model.leftOutSigmas.assign(static_cast<std::size_t>(x.rows()), 0.0);
  parallelFor(static_cast<int>(clips), threads, [&](int c) {
    MatrixXd predicted;
    VectorXd sigma;
    crossValidate(x, basis.coords, best, predicted, sigma, start[c], start[c + 1]);
    const VectorXd error = meanVertexError(predicted, basis.coords, basis.components);
    out[c].frames = clipSizes[c];
    out[c].withAll = withAll;
    out[c].without = clipMeans(error);
    for (int f = start[c]; f < start[c + 1]; ++f) {  // this clip's frames, its own segment
      model.leftOutErrors[static_cast<std::size_t>(f)] = error[f];
      model.leftOutSigmas[static_cast<std::size_t>(f)] = sigma[f];
    }
  });
  return out;
}

/// The frames of each clip: begin and end rows of the reference frames, clip after clip.
std::vector<int> clipStarts(const std::vector<int>& clipSizes) {
  std::vector<int> start = {0};
  for (int size : clipSizes) {
    start.push_back(start.back() + size);
  }
  return start;
}

/// Leaves each clip out in turn and predicts its frames by the model over the other clips,
/// mixed (mixtureShares) with each other clip's own model at each of `weights` (0 = not mixed):
/// the mean vertex error over every left-out frame per weight. The kernel
/// settings are those chosen over every clip.
std::vector<ClipMixtureTrial> clipMixtureTrials(const MatrixXd& x, const OffsetBasis& basis,
                                                const KernelFit& c,
                                                const std::vector<int>& clipSizes,
                                                const std::vector<double>& weights, int threads) {
  const int t = static_cast<int>(x.rows());
  const int clips = static_cast<int>(clipSizes.size());
  const std::vector<int> start = clipStarts(clipSizes);
  const MatrixXd kAll = kernelMatrix(x, x, c.lengthScale, c.linearWeight);
  const auto frames = [&](int clip, bool in) {
    std::vector<int> out;
    for (int f = 0; f < t; ++f) {
      if ((f >= start[clip] && f < start[clip + 1]) == in) {
        out.push_back(f);
      }
    }
    return out;
  };
  // Tasks 0..clips-1: the model over every other clip predicts clip k (rows of `left`); tasks
  // clips..2 clips-1: clip j's own model predicts every other clip's frames.
  MatrixXd left(t, basis.coords.cols());
  VectorXd leftVariance(t);
  std::vector<MatrixXd> own(static_cast<std::size_t>(clips), MatrixXd(t, basis.coords.cols()));
  std::vector<VectorXd> ownVariance(static_cast<std::size_t>(clips), VectorXd::Zero(t));
  parallelFor(2 * clips, threads, [&](int task) {
    const int k = task % clips;
    if (task < clips) {
      predictFrom(kAll, basis.coords, c.ridge, frames(k, false), frames(k, true), left,
                  leftVariance);
    } else {
      predictFrom(kAll, basis.coords, c.ridge, frames(k, true), frames(k, false), own[k],
                  ownVariance[k]);
    }
  });
  std::vector<ClipMixtureTrial> trials(weights.size());
  parallelFor(static_cast<int>(trials.size()), threads, [&](int w) {
    const double weight = weights[static_cast<std::size_t>(w)];
    MatrixXd mixed = left;
    if (weight > 0.0) {
      for (int k = 0; k < clips; ++k) {
        for (int f = start[k]; f < start[k + 1]; ++f) {
          std::vector<double> variances;
          for (int j = 0; j < clips; ++j) {
            if (j != k) {
              variances.push_back(ownVariance[j][f]);
            }
          }
          const std::vector<double> share = mixtureShares(weight, leftVariance[f], variances);
          mixed.row(f) = share[0] * left.row(f);
          for (int j = 0, s = 1; j < clips; ++j) {
            if (j != k) {
              mixed.row(f) += share[s++] * own[j].row(f);
            }
          }
        }
      }
    }
    const VectorXd error = meanVertexError(mixed, basis.coords, basis.components);
    trials[w] = {weight, error.mean(), std::vector<double>(error.data(), error.data() + t)};
  });
  return trials;
}

/// Sets the model's per-clip mixture (PoseModel::clipMixtureWeight, clipSizes): `weight` when
/// it is positive, else (kAutoClipMixture) the weight of kClipMixtureWeights with the smallest
/// left-out error (clipMixtureTrials) when that is at least 1% below the model over every clip
/// alone. The verdict is then calibrated on the mixture's left-out errors, the prediction a
/// bake makes (PoseModel::leftOutErrors).
void chooseClipMixture(PoseModel& model, const MatrixXd& x, const OffsetBasis& basis,
                       const KernelFit& best, const std::vector<int>& clipSizes, double weight,
                       int threads) {
  const std::vector<double> weights =
      weight > 0.0 ? std::vector<double>{0.0, weight}
                   : std::vector<double>(kClipMixtureWeights.begin(), kClipMixtureWeights.end());
  model.clipMixtureTrials = clipMixtureTrials(x, basis, best, clipSizes, weights, threads);
  const std::vector<ClipMixtureTrial>& trials = model.clipMixtureTrials;
  const ClipMixtureTrial& chosen = *std::min_element(
      trials.begin(), trials.end(), [](const ClipMixtureTrial& a, const ClipMixtureTrial& b) {
        return a.leftOutError < b.leftOutError;
      });
  constexpr double kGain = 0.99;
  const ClipMixtureTrial* kept =
      weight > 0.0 ? &trials.back()
      : chosen.weight > 0.0 && chosen.leftOutError < kGain * trials.front().leftOutError ? &chosen
                                                                                         : nullptr;
  if (kept != nullptr) {
    model.clipMixtureWeight = kept->weight;
    model.clipSizes = clipSizes;
    model.leftOutErrors = kept->frameErrors;
  }
}

/// Per clip, its own model's coefficients (PoseModel::clipCoefficients, rank x T as doubles):
/// (K_k + lambda I)^-1 times its frames' first `r` coordinates.
MatrixXd clipCoefficients(const MatrixXd& x, const OffsetBasis& basis, const PoseModel& model,
                          int r) {
  const int t = static_cast<int>(x.rows());
  const std::vector<int> start = clipStarts(model.clipSizes);
  MatrixXd out(r, t);
  for (std::size_t k = 0; k + 1 < start.size(); ++k) {
    const int count = start[k + 1] - start[k];
    const MatrixXd rows = x.middleRows(start[k], count);
    MatrixXd kk = kernelMatrix(rows, rows, model.lengthScale, model.linearWeight);
    kk.diagonal().array() += model.ridge;
    out.middleCols(start[k], count) =
        kk.llt().solve(basis.coords.block(start[k], 0, count, r)).transpose();
  }
  return out;
}

/// The full fit and its low-rank basis: c(x) = S_r U_r^T (K + lambda I)^-1 k(x) weighs the
/// first `r` components. Stores the coefficients, the basis and the features as floats.
void storeFit(PoseModel& model, const MatrixXd& x, const OffsetBasis& basis, int r) {
  const int t = static_cast<int>(x.rows());
  const int d = model.featureCount();
  const std::size_t dd = static_cast<std::size_t>(basis.components.cols());
  MatrixXd k = kernelMatrix(x, x, model.lengthScale, model.linearWeight);
  k.diagonal().array() += model.ridge;
  const MatrixXd coefficients = k.llt().solve(basis.coords.leftCols(r)).transpose();  // r x T
  model.coefficients.resize(static_cast<std::size_t>(r) * t);
  model.basis.resize(static_cast<std::size_t>(r) * dd);
  for (int j = 0; j < r; ++j) {
    for (int f = 0; f < t; ++f) {
      model.coefficients[static_cast<std::size_t>(j) * t + f] =
          static_cast<float>(coefficients(j, f));
    }
    for (std::size_t i = 0; i < dd; ++i) {
      model.basis[j * dd + i] =
          static_cast<float>(basis.components(j, static_cast<Eigen::Index>(i)));
    }
  }
  if (model.clipMixtureWeight > 0.0) {
    const MatrixXd own = clipCoefficients(x, basis, model, r);
    model.clipCoefficients.resize(static_cast<std::size_t>(r) * t);
    for (int j = 0; j < r; ++j) {
      for (int f = 0; f < t; ++f) {
        model.clipCoefficients[static_cast<std::size_t>(j) * t + f] = static_cast<float>(own(j, f));
      }
    }
  }
  model.features.resize(static_cast<std::size_t>(t) * d);
  for (int f = 0; f < t; ++f) {
    for (int c = 0; c < d; ++c) {
      model.features[static_cast<std::size_t>(f) * d + c] = static_cast<float>(x(f, c));
    }
  }
}

/// The build log's verdict line: the bound, the smallest it gets, and the share of the held-out
/// reference frames it calls enough at each of kVerdictOutlookShares of the rest cloth's
/// (`cloth`) diagonal.
void logVerdict(const PoseModel& model, const Mesh& cloth, std::ostream& log) {
  log << "  verdict: error bound = predicted error + " << model.verdictMargin << " (holds on "
      << 100.0 * model.verdictLevel << "% of the held-out reference frames), never below "
      << model.smallestErrorBound() << " (" << percentOfDiagonal(model.smallestErrorBound(), cloth)
      << "% of the cloth's rest diagonal); held-out reference frames it calls enough at";
  const char* separator = " ";
  for (const VerdictOutlook& at : verdictOutlook(model, cloth)) {
    log << separator << 100.0 * at.share << "%: " << std::lround(100.0 * at.enough) << "%";
    separator = ", ";
  }
  log << " of the diagonal\n";
}

}  // namespace

double heldOutEnoughShare(const PoseModel& model, double tolerance) {
  const std::vector<double>& sigmas = heldOutSigmas(model);
  if (sigmas.empty()) {
    return 0.0;
  }
  const auto within = std::count_if(sigmas.begin(), sigmas.end(), [&](double sigma) {
    return model.errorBound(sigma) <= tolerance;
  });
  return static_cast<double>(within) / static_cast<double>(sigmas.size());
}

std::vector<VerdictOutlook> verdictOutlook(const PoseModel& model, const Mesh& cloth) {
  const double diagonal = boundsDiagonal(cloth);
  std::vector<VerdictOutlook> out;
  for (double share : kVerdictOutlookShares) {
    out.push_back({share, share * diagonal, heldOutEnoughShare(model, share * diagonal)});
  }
  return out;
}

double percentOfDiagonal(double value, const Mesh& cloth) {
  return std::round(10000.0 * value / boundsDiagonal(cloth)) / 100.0;
}

int historyFramesFor(const PoseModelOptions& options, int clipCount) {
  if (options.historyFrames != kAutoHistory) {
    return options.historyFrames;
  }
  return clipCount >= 3 ? 30 : 15;
}

PoseModel fitPoseModel(const Mesh& driver, const Mesh& driven, const float* driverFrames,
                       const float* drivenFrames, const std::vector<int>& frames,
                       const std::vector<SurfaceHit>& restHits, const PoseModelOptions& options,
                       std::ostream* log, const EarlierFrames& history) {
  const int t = static_cast<int>(frames.size());
  if (t < 10) {
    DS_THROW(kInput, "the pose model needs at least 10 reference frames (got ", t,
             "); give `db build` a longer reference clip or build with --model none");
  }
  const int threads = resolveThreads(options.threads);
  PoseModel model;
  model.up = options.up;
  model.velocityLag = options.velocityLag;
  model.historyFrames =
      historyFramesFor(options, std::max(1, static_cast<int>(options.clipSizes.size())));
  model.frames = frames;
  setRigidParts(model, driver, driverFrames, t, options, threads, log);
  model.siblingWeight = model.siblingPairs().empty() ? 0.0 : options.siblingWeight;
  if (log != nullptr && model.siblingWeight > 0.0) {
    *log << "  pose model: sibling parts";
    for (const std::array<int, 2>& pair : model.siblingPairs()) {
      *log << " " << pair[0] << "-" << pair[1];
    }
    *log << " see each other (weight " << model.siblingWeight << ")\n";
  }

  // Features of every reference frame.
  model.lengthScale = 1.0;  // placeholder until chosen; the predictor below needs a valid model
  const PosePredictor shapeOnly(model, driver);
  const int d = model.featureCount();
  // Rounded to the float the database stores, so that the fit and the evaluation compare the
  // same numbers.
  const MatrixXd x =
      shapeOnly.blockFeatures(driverFrames, frames, history, threads).cast<float>().cast<double>();
  const OffsetBasis basis =
      offsetBasis(localOffsetTargets(driver, driven, driverFrames, drivenFrames, t, restHits));

  const KernelFit best = chooseKernel(x, basis.coords, threads);
  model.lengthScale = best.lengthScale;
  model.linearWeight = best.linearWeight;
  model.ridge = best.ridge;
  fitErrorPredictor(model, x, basis, best);
  if (options.clipSizes.size() > 1) {
    if (std::accumulate(options.clipSizes.begin(), options.clipSizes.end(), 0) != t ||
        *std::min_element(options.clipSizes.begin(), options.clipSizes.end()) < 1) {
      DS_THROW(kInput, "the reference clips' frame counts do not add up to the ", t,
               " frames given");
    }
    model.clipErrors = clipContributions(model, x, basis, best, options.clipSizes, threads);
    // Auto needs three clips: with two, each left-out clip is predicted by the other clip's
    // model with or without the mixture, so the trials cannot tell them apart.
    if (options.clipMixtureWeight > 0.0 ||
        (options.clipMixtureWeight == kAutoClipMixture && options.clipSizes.size() >= 3)) {
      chooseClipMixture(model, x, basis, best, options.clipSizes, options.clipMixtureWeight,
                        threads);
    }
  }
  calibrateVerdict(model, options.verdictLevel);
  // The basis keeps the first `rank` components.
  const int r = std::min(std::min(t, std::max(1, options.rank)), basis.rank);
  storeFit(model, x, basis, r);
  if (log != nullptr) {
    *log << "  pose model: " << t << " frames, " << d << " features, rank " << r
         << ", length scale " << model.lengthScale << ", linear " << model.linearWeight
         << ", ridge " << model.ridge << "; cross-validated mean error "
         << model.crossValidationError << " (binding " << model.bindingError
         << "), predicted error " << model.errorBias << " + " << model.errorScale << " sigma\n";
    logVerdict(model, driven, *log);
    if (!model.clipMixtureTrials.empty()) {
      *log << "  per-clip models, each clip left out in turn: mean error";
      for (const ClipMixtureTrial& trial : model.clipMixtureTrials) {
        *log << (trial.weight > 0.0 ? ", at weight " : " ");
        if (trial.weight > 0.0) {
          *log << trial.weight << " ";
        }
        *log << trial.leftOutError << (trial.weight > 0.0 ? "" : " without them");
      }
      if (model.clipMixtureWeight > 0.0) {
        *log << "; mixed in at weight " << model.clipMixtureWeight << "\n";
      } else {
        *log << "; not used\n";
      }
    } else if (options.clipMixtureWeight > 0.0 && options.clipSizes.size() < 2) {
      *log << "  per-clip models: one reference clip, nothing to mix (give more with --also)\n";
    }
  }
  return model;
}

}  // namespace drivenshape
