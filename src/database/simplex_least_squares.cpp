// SPDX-License-Identifier: Apache-2.0
#include "qp.h"

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
/// How far sum(lower) may exceed 1, or sum(upper) fall short of it: rounding of the previous
/// frame's weights (their sum is checked against kSumLimit).
constexpr double kBoxSumSlack = kSumLimit;
/// A box whose lower corner sums to at least 1 - kPinnedSlack (or upper corner to at most
/// 1 + kPinnedSlack) is treated as the single point it admits.
constexpr double kPinnedSlack = 1e-12;

/// The preconditions of the bounded solve (see qp.h); a violation is a caller's bug.
void checkBounds(int k, const Eigen::Ref<const Eigen::VectorXd>& lower,
                 const Eigen::Ref<const Eigen::VectorXd>& upper) {
  if (lower.size() != k || upper.size() != k) {
    DS_THROW(kInternal, "constrained blend weights: bounds of ", lower.size(), " and ",
             upper.size(), " entries; ", k, " expected for ", k, " shapes");
  }
  for (int i = 0; i < k; ++i) {
    // Written so that NaN fails too.
    if (!(lower(i) >= 0.0 && lower(i) <= upper(i) && upper(i) <= 1.0)) {
      DS_THROW(kInternal, "constrained blend weights: bounds of shape ", i, " are [", lower(i),
               ", ", upper(i), "]; 0 <= lower <= upper <= 1 is required");
    }
  }
  const double lowSum = lower.sum();
  const double highSum = upper.sum();
  if (!(lowSum <= 1.0 + kBoxSumSlack && highSum >= 1.0 - kBoxSumSlack)) {
    DS_THROW(kInternal, "constrained blend weights: the bounds admit no weights summing to 1 ",
             "(sum of lower bounds ", lowSum, ", of upper bounds ", highSum, ")");
  }
}

/// The inputs of a bounded solve (see qp.h); a wrong size or bound is a caller's bug
/// (Error(kInternal)), a non-finite projection a broken frame (Error(kNumerical)).
void checkProjectedInputs(int k, const Eigen::Ref<const Eigen::VectorXd>& p, double rr, double bb,
                          const Eigen::Ref<const Eigen::VectorXd>& lower,
                          const Eigen::Ref<const Eigen::VectorXd>& upper) {
  if (p.size() != k - 1) {
    DS_THROW(kInternal, "constrained blend weights: the projection has ", p.size(), " entries; ",
             k - 1, " expected for ", k, " shapes");
  }
  checkBounds(k, lower, upper);
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
}

/// The factors of a SimplexLeastSquares that the solve steps read (see the class members).
struct SimplexFactors {
  int k;                     // shapes
  const Eigen::MatrixXd& z;  // k by k-1
  const Eigen::MatrixXd& r;  // k-1 by k-1, upper triangular
  const Eigen::MatrixXd& c;  // k-1 by 2k
  double lambda;
};

/// The QP in y for a box that is not pinned. Same constraint normals as [0, 1], other
/// right-hand sides: Z_i y >= l_i - 1/k and -Z_i y >= 1/k - u_i. (For l = 0, u = 1: -1/k and
/// 1/k - 1.) Throws Error(kNumerical) if the solver finds the box infeasible.
QpResult solveBoxQp(const SimplexFactors& f, const Eigen::Ref<const Eigen::VectorXd>& p,
                    const Eigen::Ref<const Eigen::VectorXd>& lower,
                    const Eigen::Ref<const Eigen::VectorXd>& upper) {
  const int k = f.k;
  Eigen::VectorXd bounds(2 * k);
  for (int i = 0; i < k; ++i) {
    bounds(i) = lower(i) - 1.0 / k;
    bounds(k + i) = 1.0 / k - upper(i);
  }
  const Eigen::MatrixXd noEqualities(k - 1, 0);
  const Eigen::VectorXd noBounds(0);
  QpResult qp = detail::solveGoldfarbIdnani(f.r, -p, noEqualities, noBounds, f.c, bounds);
  if (!qp.feasible) {
    // Cannot happen in exact arithmetic: the preconditions make the box meet the simplex.
    DS_THROW(kNumerical,
             "constrained blend weights: the QP solver reported the bound constraints "
             "infeasible for ",
             k, " shapes (after ", qp.iterations, " iterations)");
  }
  return qp;
}

/// Clean-up of the QP's weights w. The QP keeps only an independent subset of the tight
/// bounds active (`active`), so:
///  * weights with an active bound are set to that bound exactly; the others are clamped to
///    their box (a clamp moves a weight by at most the bound violation, which is rounding),
///    and those that reach their upper bound are held there too;
///  * the free weights then share what the held ones leave of the sum, T = 1 - sum(held) -
///    sum(lower of free). T <= 0 puts them all at their lower bound (with [0, 1] bounds: one
///    weight at 1, all others 0); T >= the total width of their boxes puts them all at their
///    upper bound (with [0, 1]: the one weight left when k-1 are at 0 is 1); otherwise their
///    excess over the lower bound is divided by (its sum / T). With [0, 1] that is the plain
///    division by the sum, which keeps every weight in [0, 1] exactly (each is at most the
///    sum) and leaves |sum - 1| at a few ulps; in general a weight can overshoot its upper
///    bound by rounding and is clamped back. The division moves a weight by at most
///    |sum - 1| before it, which the checks bound by kSumLimit.
void cleanUpWeights(int k, const std::vector<int>& active,
                    const Eigen::Ref<const Eigen::VectorXd>& lower,
                    const Eigen::Ref<const Eigen::VectorXd>& upper, Eigen::VectorXd& w) {
  std::vector<char> held(k, 0);
  std::vector<char> atLower(k, 0);
  std::vector<char> atUpper(k, 0);
  for (const int id : active) {
    (id < k ? atLower[id] : atUpper[id - k]) = 1;
  }
  for (int i = 0; i < k; ++i) {
    if (atUpper[i]) {
      w(i) = upper(i);
    } else if (atLower[i]) {
      w(i) = lower(i);
    } else {
      w(i) = std::clamp(w(i), lower(i), upper(i));
    }
    held[i] = atLower[i] || atUpper[i] || w(i) >= upper(i);
  }
  // base: the held weights and the lower bounds of the free ones; excess: the free weights
  // above their lower bound.
  Eigen::VectorXd base(k);
  Eigen::VectorXd excess(k);
  double width = 0.0;
  for (int i = 0; i < k; ++i) {
    base(i) = held[i] ? w(i) : lower(i);
    excess(i) = held[i] ? 0.0 : w(i) - lower(i);
    width += held[i] ? 0.0 : upper(i) - lower(i);
  }
  const double target = 1.0 - base.sum();
  const bool anyFree = std::find(held.begin(), held.end(), 0) != held.end();
  if (anyFree && target <= 0.0) {
    excess.setZero();
  } else if (anyFree && target >= width) {
    for (int i = 0; i < k; ++i) {
      excess(i) = held[i] ? 0.0 : upper(i) - lower(i);
    }
  } else if (anyFree) {
    const double sum = excess.sum();
    if (sum > 0.0 && std::abs(sum - target) <= kSumLimit) {
      excess /= sum / target;
    }
  }
  for (int i = 0; i < k; ++i) {
    if (!held[i]) {
      w(i) = std::min(lower(i) + excess(i), upper(i));
    }
  }
}

/// The relative KKT residual of the weights y = Z^T (w - 1/k) (Ry = R y) and the QP's active
/// bounds. The gradient of 1/2 |A w - b|^2 in y, M^T M y - p, must equal sum_j u_j n_j over
/// the active bounds with u_j >= 0. The residual is taken back to w-space (Z times it; the
/// component along 1 belongs to the multiplier of the sum) and measured in the max norm,
/// together with any negative multiplier, relative to max(trace(M^T M), |p|_inf): the sizes
/// of the two terms of the gradient (|M^T M| <= trace, |y| < 1).
double kktResidualOf(const SimplexFactors& f, const Eigen::Ref<const Eigen::VectorXd>& p,
                     const Eigen::VectorXd& y, const Eigen::VectorXd& Ry, const QpResult& qp) {
  Eigen::VectorXd stationarity = f.r.triangularView<Eigen::Upper>().transpose() * Ry;
  stationarity -= f.lambda * y + p;
  double dualViolation = 0.0;
  for (std::size_t j = 0; j < qp.active.size(); ++j) {
    stationarity -= qp.multipliers(static_cast<Eigen::Index>(j)) * f.c.col(qp.active[j]);
    dualViolation = std::max(dualViolation, -qp.multipliers(static_cast<Eigen::Index>(j)));
  }
  const double gramTrace = std::max(f.r.squaredNorm() - f.lambda * (f.k - 1), 0.0);  // trace(M^T M)
  const double kktScale = std::max(gramTrace, p.cwiseAbs().maxCoeff());
  const double kktAbsolute = std::max((f.z * stationarity).cwiseAbs().maxCoeff(), dualViolation);
  return kktScale > 0.0 ? kktAbsolute / kktScale : kktAbsolute;
}

/// Throws Error(kNumerical) when a solution fails the sum, bound or KKT check (see qp.h).
void checkSimplexSolution(int k, const SimplexSolution& solution) {
  if (solution.sumError > kSumLimit || solution.boundViolation > kBoundLimit ||
      !(solution.kktResidual <= kKktLimit)) {
    DS_THROW(kNumerical, "constrained blend weights failed their checks (", k,
             " shapes): |sum(w) - 1| = ", solution.sumError, " (limit ", kSumLimit,
             "), bound violation before clamping = ", solution.boundViolation, " (limit ",
             kBoundLimit, "), relative KKT residual = ", solution.kktResidual, " (limit ",
             kKktLimit, "); the database shapes may be nearly degenerate: try a larger ridge");
  }
}

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
  for (int i = 0; i < k; ++i) {
    mC.col(i) = mZ.row(i).transpose();
    mC.col(k + i) = -mZ.row(i).transpose();
  }
}

SimplexSolution SimplexLeastSquares::solveProjected(const Eigen::Ref<const Eigen::VectorXd>& p,
                                                    double rr, double bb) const {
  const int k = mShapeCount;
  return solveProjected(p, rr, bb, Eigen::VectorXd::Zero(k), Eigen::VectorXd::Ones(k));
}

SimplexSolution SimplexLeastSquares::solveProjected(
    const Eigen::Ref<const Eigen::VectorXd>& p, double rr, double bb,
    const Eigen::Ref<const Eigen::VectorXd>& lower,
    const Eigen::Ref<const Eigen::VectorXd>& upper) const {
  const int k = mShapeCount;
  checkProjectedInputs(k, p, rr, bb, lower, upper);

  SimplexSolution solution;
  if (k == 1) {
    solution.weights = Eigen::VectorXd::Ones(1);
    solution.atOne = {0};
    solution.objective = std::max(rr, 0.0);
    solution.relativeResidual = bb > 0.0 ? std::sqrt(solution.objective / bb) : 0.0;
    return solution;
  }

  // A box whose lower (or upper) corner already sums to 1 admits that corner alone. The QP
  // would meet k tight, dependent bounds there, which rounding can make look inconsistent.
  const bool pinnedLow = lower.sum() >= 1.0 - kPinnedSlack;
  const bool pinnedHigh = upper.sum() <= 1.0 + kPinnedSlack;
  const SimplexFactors factors{k, mZ, mR, mC, mLambda};
  Eigen::VectorXd w(k);
  QpResult qp;
  if (pinnedLow || pinnedHigh) {
    w = pinnedLow ? lower : upper;
  } else {
    qp = solveBoxQp(factors, p, lower, upper);
    solution.iterations = qp.iterations;
    w = (mZ * qp.x).array() + 1.0 / k;
  }
  for (int i = 0; i < k; ++i) {
    solution.boundViolation = std::max({solution.boundViolation, lower(i) - w(i), w(i) - upper(i)});
  }
  if (!pinnedLow && !pinnedHigh) {
    cleanUpWeights(k, qp.active, lower, upper, w);
  }
  for (int i = 0; i < k; ++i) {
    if (w(i) == lower(i)) {
      solution.atZero.push_back(i);
    } else if (w(i) == upper(i)) {
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

  // A pinned box has a single feasible point, where every gradient is balanced by the bounds'
  // multipliers: KKT residual 0.
  if (!pinnedLow && !pinnedHigh) {
    solution.kktResidual = kktResidualOf(factors, p, y, Ry, qp);
  }
  checkSimplexSolution(k, solution);
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
