// SPDX-License-Identifier: Apache-2.0
// Which frames to simulate next (drivenshape/pose_model.h, suggestFrames): greedy reduction of
// the pose model's Gaussian-process variance over the shot frames.
//
// With the reference features X, the kernel k and the ridge lambda as observation noise, the
// posterior covariance of two poses is
//
//   S(a, b) = k(a, b) - k(a, X) (K + lambda I)^-1 k(X, b) = k(a, b) - A(a)^T A(b),
//   A(.) = L^-1 k(X, .),   K + lambda I = L L^T,
//
// and one more observation of pose c (noise lambda) changes it by a rank-one step:
//
//   S'(a, b) = S(a, b) - g(a) g(b),   g(.) = S(., c) / sqrt(S(c, c) + lambda).
//
// The greedy keeps S(shot, candidate) (S x C), the shots' and candidates' variances and the
// steps g taken so far; a candidate's column S(., c) is recomputed from them when it is picked.

#include <drivenshape/pose_model.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include <drivenshape/error.h>

#include "parallel.h"
#include "pose_kernel.h"

namespace drivenshape {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

/// The prior variance k(x, x) of every row.
VectorXd priorVariance(const MatrixXd& rows, double linearWeight) {
  return (linearWeight * rows.rowwise().squaredNorm()).array() + 1.0;
}

}  // namespace

std::vector<FrameSuggestion> suggestFrames(const PoseModel& model,
                                           const Eigen::Ref<const Eigen::MatrixXd>& candidates,
                                           const Eigen::Ref<const Eigen::MatrixXd>& shots,
                                           int count, int threads) {
  if (count < 1) {
    DS_THROW(kUsage, "the number of frames to suggest must be at least 1 (got ", count, ")");
  }
  if (model.empty() || model.coefficients.empty()) {
    DS_THROW(kInput, "suggesting frames needs a fitted pose model (build with --model pose)");
  }
  const int t = model.frameCount(), d = model.featureCount();
  if (candidates.cols() != d || shots.cols() != d) {
    DS_THROW(kInput, "suggesting frames: the candidate and shot features have ", candidates.cols(),
             " and ", shots.cols(), " columns but the pose model has ", d, " features");
  }
  if (candidates.rows() == 0 || shots.rows() == 0) {
    DS_THROW(kInput, "suggesting frames needs at least one candidate and one shot frame (got ",
             candidates.rows(), " and ", shots.rows(), ")");
  }
  const int c = static_cast<int>(candidates.rows()), s = static_cast<int>(shots.rows());
  const double lambda = model.ridge, ls = model.lengthScale, lw = model.linearWeight;
  const MatrixXd x =
      Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          model.features.data(), t, d)
          .cast<double>();
  const MatrixXd cand = candidates, shot = shots;

  MatrixXd k = poseKernel(x, x, ls, lw);
  k.diagonal().array() += lambda;
  const Eigen::LLT<MatrixXd> llt(k);
  if (llt.info() != Eigen::Success) {
    DS_THROW(kNumerical,
             "suggesting frames: the pose model's kernel matrix is not positive "
             "definite; rebuild the database");
  }
  const MatrixXd ac = llt.matrixL().solve(poseKernel(x, cand, ls, lw));   // T x C
  const MatrixXd as = llt.matrixL().solve(poseKernel(x, shot, ls, lw));   // T x S
  MatrixXd cross = poseKernel(shot, cand, ls, lw) - as.transpose() * ac;  // S x C
  VectorXd shotVariance = priorVariance(shot, lw) - as.colwise().squaredNorm().transpose();
  VectorXd candidateVariance = priorVariance(cand, lw) - ac.colwise().squaredNorm().transpose();
  MatrixXd steps(0, c);  // one row g per suggestion, over the candidates

  const auto meanSigma = [&](const VectorXd& variance) {
    double sum = 0.0;
    for (int i = 0; i < s; ++i) {
      sum += std::sqrt(std::max(0.0, variance[i]));
    }
    return sum / s;
  };
  std::vector<bool> taken(static_cast<std::size_t>(c), false);
  std::vector<double> score(static_cast<std::size_t>(c));
  std::vector<FrameSuggestion> out;
  const int wanted = std::min(count, c);
  for (int step = 0; step < wanted; ++step) {
    // Each candidate's sum of shot deviations once it is observed.
    parallelFor(c, threads, [&](int j) {
      if (taken[j]) {
        score[j] = std::numeric_limits<double>::infinity();
        return;
      }
      const double scale = 1.0 / (candidateVariance[j] + lambda);
      double sum = 0.0;
      for (int i = 0; i < s; ++i) {
        const double g = cross(i, j);
        sum += std::sqrt(std::max(0.0, shotVariance[i] - g * g * scale));
      }
      score[j] = sum;
    });
    int best = -1;
    for (int j = 0; j < c; ++j) {
      if (!taken[j] && (best < 0 || score[j] < score[best])) {
        best = j;
      }
    }
    FrameSuggestion suggestion;
    suggestion.candidate = best;
    suggestion.sigmaBefore = meanSigma(shotVariance);
    suggestion.sigmaAfter = score[best] / s;
    suggestion.errorBefore = model.predictedError(suggestion.sigmaBefore);
    suggestion.errorAfter = model.predictedError(suggestion.sigmaAfter);
    out.push_back(suggestion);

    // The rank-one step: the picked candidate's posterior covariance with every candidate.
    const VectorXd column = poseKernel(cand, cand.row(best), ls, lw).col(0) -
                            ac.transpose() * ac.col(best) - steps.transpose() * steps.col(best);
    const double root = std::sqrt(candidateVariance[best] + lambda);
    const VectorXd gc = column / root;
    const VectorXd gs = cross.col(best) / root;
    cross.noalias() -= gs * gc.transpose();
    shotVariance -= gs.cwiseAbs2();
    candidateVariance -= gc.cwiseAbs2();
    steps.conservativeResize(steps.rows() + 1, Eigen::NoChange);
    steps.row(steps.rows() - 1) = gc.transpose();
    taken[best] = true;
  }
  return out;
}

}  // namespace drivenshape
