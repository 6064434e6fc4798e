#include <drivenshape/qp.h>

#include <drivenshape/error.h>

#include "goldfarb_idnani.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <vector>

// The weights problem in the coordinates y of the plane sum(w) = 1:
//
//     w = 1/k + Z y               Z: k by k-1, orthonormal columns, Z^T 1 = 0
//     A w - b = M y - (b - m)     M = A Z, m = A 1/k
//
//     minimise 1/2 y^T (R^T R) y - p^T y     (= 1/2 |M y - (b - m)|^2 - rr/2 + ridge term)
//     s.t.      Z_i y >= -1/k                (w_i >= 0)
//              -Z_i y >= 1/k - 1             (w_i <= 1)
//
// with R the triangle of the thin QR of [M; sqrt(lambda) I]. The k bounds w_i >= 0, w_i <= 1
// and the eliminated sum are linearly dependent (one weight at 1 <=> all others at 0); the
// Goldfarb-Idnani solver keeps only an independent subset active, and the clean-up below
// restores the full picture.

namespace drivenshape {
namespace {

/// Limits of the checks made on every solution (see qp.h).
constexpr double kSumLimit = 1e-9;
constexpr double kBoundLimit = 1e-9;
constexpr double kKktLimit = 1e-6;

}  // namespace

SimplexLeastSquares::SimplexLeastSquares(const Eigen::Ref<const Eigen::MatrixXd>& shapes,
                                         double ridge)
    : mShapeCount(static_cast<int>(shapes.cols())), mRowCount(static_cast<int>(shapes.rows())) {
  const int k = mShapeCount;
  const int n = mRowCount;
  if (k < 1) {
    DS_THROW(kInput, "constrained blend weights need at least one database shape (got 0)");
  }
  if (!(ridge > 0.0) || !std::isfinite(ridge)) {
    DS_THROW(kUsage, "constrained blend weights: the ridge must be positive and finite (got ",
             ridge, ")");
  }
  for (int col = 0; col < k; ++col) {
    for (int row = 0; row < n; ++row) {
      if (!std::isfinite(shapes(row, col))) {
        DS_THROW(kNumerical, "database shape ", col, " has a non-finite value (", shapes(row, col),
                 ") at row ", row, " (vertex ", row / 3, ", axis ", "xyz"[row % 3],
                 "); fix or remove that shape");
      }
    }
  }

  mCenter = shapes.rowwise().mean();
  mZ.resize(k, k - 1);
  if (k == 1) {
    mBasis.resize(n, 0);
    mR.resize(0, 0);
    mC.resize(0, 0);
    mCBound.resize(0);
    return;
  }

  // Householder reflection H = I - 2 v v^T / (v^T v), v = u + e1, u = 1/sqrt(k): H u = -e1, so
  // H is symmetric orthogonal and its columns 1..k-1 are orthonormal and orthogonal to u.
  // (u + e1 has no cancellation: both first entries are positive.)
  Eigen::VectorXd v = Eigen::VectorXd::Constant(k, 1.0 / std::sqrt(static_cast<double>(k)));
  v(0) += 1.0;
  const double scale = 2.0 / v.squaredNorm();
  for (int col = 1; col < k; ++col) {
    for (int row = 0; row < k; ++row) {
      mZ(row, col - 1) = (row == col ? 1.0 : 0.0) - scale * v(row) * v(col);
    }
  }

  // M = (A - m 1^T) Z: the same matrix as A Z, but without summing large common offsets
  // (shapes 1000 units from the origin) that cancel.
  const Eigen::MatrixXd centered = shapes.colwise() - mCenter;
  mBasis.noalias() = centered * mZ;

  const double trace = mBasis.squaredNorm();  // trace(M^T M)
  // All shapes equal (M = 0): any weights fit equally well; the ridge then picks the uniform
  // weights, with a lambda of the ridge itself (its size does not matter).
  mLambda = ridge * (trace > 0.0 ? trace / (k - 1) : 1.0);

  Eigen::MatrixXd stacked(n + k - 1, k - 1);
  stacked.topRows(n) = mBasis;
  stacked.bottomRows(k - 1) = std::sqrt(mLambda) * Eigen::MatrixXd::Identity(k - 1, k - 1);
  // Plain Householder QR (no column pivoting), so R is the factor of G itself and not of a
  // permuted G. The ridge rows make it full rank whatever M is.
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(stacked);
  mR = qr.matrixQR().topRows(k - 1).triangularView<Eigen::Upper>();

  mC.resize(k - 1, 2 * k);
  mCBound.resize(2 * k);
  for (int i = 0; i < k; ++i) {
    mC.col(i) = mZ.row(i).transpose();
    mC.col(k + i) = -mZ.row(i).transpose();
    mCBound(i) = -1.0 / k;
    mCBound(k + i) = 1.0 / k - 1.0;
  }
}

SimplexSolution SimplexLeastSquares::solveProjected(const Eigen::Ref<const Eigen::VectorXd>& p,
                                                    double rr, double bb) const {
  const int k = mShapeCount;
  if (p.size() != k - 1) {
    DS_THROW(kInternal, "constrained blend weights: the projection has ", p.size(), " entries; ",
             k - 1, " expected for ", k, " shapes");
  }
  for (int i = 0; i < p.size(); ++i) {
    if (!std::isfinite(p(i))) {
      DS_THROW(kNumerical, "constrained blend weights: projection entry ", i, " is ", p(i),
               " (the frame's positions are not finite?)");
    }
  }
  if (!std::isfinite(rr) || !std::isfinite(bb)) {
    DS_THROW(kNumerical, "constrained blend weights: |b - m|^2 = ", rr, ", |b|^2 = ", bb,
             " (the frame's positions are not finite?)");
  }

  SimplexSolution solution;
  if (k == 1) {
    solution.weights = Eigen::VectorXd::Ones(1);
    solution.atOne = {0};
    solution.objective = std::max(rr, 0.0);
    solution.relativeResidual = bb > 0.0 ? std::sqrt(solution.objective / bb) : 0.0;
    return solution;
  }

  const Eigen::MatrixXd noEqualities(k - 1, 0);
  const Eigen::VectorXd noBounds(0);
  const QpResult qp = detail::solveGoldfarbIdnani(mR, -p, noEqualities, noBounds, mC, mCBound);
  if (!qp.feasible) {
    // Cannot happen in exact arithmetic: the uniform weights are feasible.
    DS_THROW(kNumerical,
             "constrained blend weights: the QP solver reported the simplex "
             "constraints infeasible for ",
             k, " shapes (after ", qp.iterations, " iterations)");
  }
  solution.iterations = qp.iterations;

  Eigen::VectorXd w = (mZ * qp.x).array() + 1.0 / k;
  solution.boundViolation = std::max({0.0, -w.minCoeff(), w.maxCoeff() - 1.0});

  // Clean-up. The QP keeps only an independent subset of the tight bounds active, so:
  //  * a weight whose upper bound is active, or the one weight left when k-1 lower bounds are
  //    active, is 1 and all others are 0 exactly (one-hot);
  //  * otherwise weights with an active lower bound are set to 0, the others clamped to
  //    [0, 1] (a clamp moves a weight by at most the bound violation, which is rounding), and
  //    the free weights are divided by their sum. That re-normalisation keeps every weight in
  //    [0, 1] exactly (each is at most the sum) and leaves |sum - 1| at a few ulps; it moves a
  //    weight by at most |sum - 1| before it, which the checks below bound by kSumLimit.
  std::vector<char> lower(k, 0);
  std::vector<char> upper(k, 0);
  for (const int id : qp.active) {
    (id < k ? lower[id] : upper[id - k]) = 1;
  }
  int oneHot = -1;
  const int lowerCount = static_cast<int>(std::count(lower.begin(), lower.end(), 1));
  for (int i = 0; i < k && oneHot < 0; ++i) {
    if (upper[i] || (lowerCount == k - 1 && !lower[i])) {
      oneHot = i;
    }
  }
  if (oneHot < 0) {
    for (int i = 0; i < k; ++i) {
      w(i) = lower[i] ? 0.0 : std::clamp(w(i), 0.0, 1.0);
    }
    Eigen::Index largest = 0;
    if (w.maxCoeff(&largest) >= 1.0) {
      oneHot = static_cast<int>(largest);
    }
  }
  if (oneHot >= 0) {
    w.setZero();
    w(oneHot) = 1.0;
  } else {
    const double sum = w.sum();
    if (sum > 0.0 && std::abs(sum - 1.0) <= kSumLimit) {
      w /= sum;
    }
  }
  for (int i = 0; i < k; ++i) {
    if (w(i) == 0.0) {
      solution.atZero.push_back(i);
    } else if (w(i) == 1.0) {
      solution.atOne.push_back(i);
    }
  }
  solution.weights = w;
  solution.sumError = std::abs(w.sum() - 1.0);

  // Objective of the returned weights: y = Z^T (w - 1/k), and with the unregularised Gram
  // M^T M = R^T R - lambda I,  |A w - b|^2 = y^T M^T M y - 2 p^T y + rr.
  const Eigen::VectorXd y = mZ.transpose() * (w.array() - 1.0 / k).matrix();
  const Eigen::VectorXd Ry = mR.triangularView<Eigen::Upper>() * y;
  solution.objective =
      std::max(Ry.squaredNorm() - mLambda * y.squaredNorm() - 2.0 * p.dot(y) + rr, 0.0);
  solution.relativeResidual = bb > 0.0 ? std::sqrt(solution.objective / bb) : 0.0;

  // KKT: the gradient of 1/2 |A w - b|^2 in y, M^T M y - p, must equal sum_j u_j n_j over the
  // active bounds with u_j >= 0. The residual is taken back to w-space (Z times it; the
  // component along 1 belongs to the multiplier of the sum) and measured in the max norm,
  // together with any negative multiplier, relative to max(trace(M^T M), |p|_inf): the sizes
  // of the two terms of the gradient (|M^T M| <= trace, |y| < 1).
  Eigen::VectorXd stationarity = mR.triangularView<Eigen::Upper>().transpose() * Ry;
  stationarity -= mLambda * y + p;
  double dualViolation = 0.0;
  for (std::size_t j = 0; j < qp.active.size(); ++j) {
    stationarity -= qp.multipliers(static_cast<Eigen::Index>(j)) * mC.col(qp.active[j]);
    dualViolation = std::max(dualViolation, -qp.multipliers(static_cast<Eigen::Index>(j)));
  }
  const double gramTrace = std::max(mR.squaredNorm() - mLambda * (k - 1), 0.0);  // trace(M^T M)
  const double kktScale = std::max(gramTrace, p.cwiseAbs().maxCoeff());
  const double kktAbsolute = std::max((mZ * stationarity).cwiseAbs().maxCoeff(), dualViolation);
  solution.kktResidual = kktScale > 0.0 ? kktAbsolute / kktScale : kktAbsolute;

  if (solution.sumError > kSumLimit || solution.boundViolation > kBoundLimit ||
      !(solution.kktResidual <= kKktLimit)) {
    DS_THROW(kNumerical, "constrained blend weights failed their checks (", k,
             " shapes): |sum(w) - 1| = ", solution.sumError, " (limit ", kSumLimit,
             "), bound violation before clamping = ", solution.boundViolation, " (limit ",
             kBoundLimit, "), relative KKT residual = ", solution.kktResidual, " (limit ",
             kKktLimit, "); the database shapes may be nearly degenerate: try a larger ridge");
  }
  return solution;
}

SimplexSolution SimplexLeastSquares::solve(const Eigen::Ref<const Eigen::VectorXd>& b) const {
  if (b.size() != mRowCount) {
    DS_THROW(kInternal, "constrained blend weights: the pose has ", b.size(), " values; ",
             mRowCount, " expected");
  }
  for (int row = 0; row < b.size(); ++row) {
    if (!std::isfinite(b(row))) {
      DS_THROW(kNumerical, "constrained blend weights: the pose has a non-finite value (", b(row),
               ") at row ", row, " (vertex ", row / 3, ", axis ", "xyz"[row % 3], ")");
    }
  }
  const Eigen::VectorXd offset = b - mCenter;
  const Eigen::VectorXd p = mBasis.transpose() * offset;
  return solveProjected(p, offset.squaredNorm(), b.squaredNorm());
}

}  // namespace drivenshape
