// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <Eigen/Core>
#include <vector>

namespace drivenshape {

/// Strictly convex QP by the dual active-set method of Goldfarb and Idnani (1983):
///
///     minimise   1/2 x^T G x + a^T x
///     subject to E^T x  = e      (equality constraints, columns of E)
///                C^T x >= c      (inequality constraints, columns of C)
///
/// G is given by its upper-triangular factor R (G = R^T R, R n by n, nonsingular), so callers
/// that start from a least-squares matrix pass the R of its thin QR and never square the
/// condition number. Sizes: a n; E n by me; C n by mi.
struct QpProblem {
  Eigen::MatrixXd R;
  Eigen::VectorXd a;
  Eigen::MatrixXd E;
  Eigen::VectorXd e;
  Eigen::MatrixXd C;
  Eigen::VectorXd c;
};

struct QpResult {
  Eigen::VectorXd x;
  double objective = 0.0;       ///< 1/2 x^T G x + a^T x
  std::vector<int> active;      ///< indices of active constraints (equalities first: 0..me-1,
                                ///< then me + i for inequality i). A linearly independent
                                ///< subset: an equality or inequality that depends on those
                                ///< already active is left out even when it holds with equality.
  Eigen::VectorXd multipliers;  ///< Lagrange multipliers of `active`, same order
  int iterations = 0;
  bool feasible = true;  ///< false: the constraints admit no point
};

/// Solves the problem; never throws for an infeasible problem (result.feasible = false).
/// Throws Error(kInternal) on inconsistent sizes and Error(kNumerical) on non-finite entries,
/// a singular R, or when 10 (n + me + mi) + 50 constraint additions and drops do not converge.
/// Entries of R below the diagonal are ignored. n = 0 is allowed.
QpResult solveGoldfarbIdnani(const QpProblem& problem);

/// Blend weights for DrivenShape:
///
///     minimise ||A w - b||^2  subject to  sum(w) = 1,  0 <= w_i <= 1
///
/// A is n by k (columns are the database driver shapes, flattened x0 y0 z0 x1 ...).
///
/// The equality is eliminated exactly: w = 1/k + Z y with Z an orthonormal basis of the
/// plane sum(w) = 0, so A w - b = M y - (b - m) with M = A Z (n by k-1) and m = A 1/k (the
/// mean shape). M does not depend on where the shapes sit in space (A Z = (A - t 1^T) Z), which
/// keeps the projection well conditioned in float. M is factorised once by a thin QR of
/// [M; sqrt(lambda) I], lambda = ridge * trace(M^T M) / (k-1): the ridge only matters for
/// rank-deficient databases (duplicate shapes) and moves the objective by at most 2 lambda.
///
/// Per frame, the caller provides the projection p = M^T (b - m) and the squared norm
/// ||b - m||^2 (computed by the projection kernel for whole chunks of frames), and gets the
/// weights with their checks.
struct SimplexSolution {
  Eigen::VectorXd weights;        ///< k, sum 1, in [0,1] (clamped to the bounds exactly)
  std::vector<int> atZero;        ///< shapes whose weight is held at 0 (exactly 0 in weights)
  std::vector<int> atOne;         ///< shapes whose weight is held at 1 (then all others are 0)
  double objective = 0.0;         ///< ||A w - b||^2 (ridge excluded), from the projection
  double relativeResidual = 0.0;  ///< ||A w - b|| / ||b||
  double kktResidual = 0.0;       ///< max-norm of the KKT stationarity residual in w (and of
                                  ///< any negative multiplier), over max(trace(M^T M), |p|_inf)
  double sumError = 0.0;          ///< |sum(w) - 1|
  double boundViolation = 0.0;    ///< max(0, -min w, max w - 1) before clamping
  int iterations = 0;
};

class SimplexLeastSquares {
 public:
  static constexpr double kDefaultRidge = 1e-12;

  /// `shapes` is n by k, k >= 1. Throws Error(kNumerical) on NaN or infinite entries.
  explicit SimplexLeastSquares(const Eigen::Ref<const Eigen::MatrixXd>& shapes,
                               double ridge = kDefaultRidge);

  int shapeCount() const { return mShapeCount; }
  int rowCount() const { return mRowCount; }
  /// M = A Z, n by (k-1). Rows of M^T are what the projection kernel dots with (b - m).
  const Eigen::MatrixXd& basis() const { return mBasis; }
  /// m = A 1/k, the mean shape, n.
  const Eigen::VectorXd& center() const { return mCenter; }

  /// Weights from the projection p = M^T (b - m) (k-1), rr = ||b - m||^2 and bb = ||b||^2.
  /// Throws Error(kNumerical) if the inputs are not finite or the checks fail
  /// (sum, bounds, KKT beyond 1e-6 relative).
  SimplexSolution solveProjected(const Eigen::Ref<const Eigen::VectorXd>& p, double rr,
                                 double bb) const;

  /// The same with per-shape bounds lower_i <= w_i <= upper_i in place of 0 <= w_i <= 1
  /// (temporal stability: a box of half-width tau around the previous frame's weights,
  /// intersected with [0, 1]). Requires 0 <= lower <= upper <= 1 and
  /// sum(lower) <= 1 <= sum(upper) to within 1e-9 (always true for a box around weights that
  /// sum to 1); throws Error(kInternal) otherwise. A box whose lower (upper) corner sums to 1
  /// admits that corner alone, which is returned (kktResidual 0, iterations 0). atZero/atOne then
  /// list shapes held at their lower and upper bound. With lower = 0 and upper = 1 the result is
  /// that of the overload above.
  SimplexSolution solveProjected(const Eigen::Ref<const Eigen::VectorXd>& p, double rr, double bb,
                                 const Eigen::Ref<const Eigen::VectorXd>& lower,
                                 const Eigen::Ref<const Eigen::VectorXd>& upper) const;

  /// Convenience for one frame: computes the projection on the host.
  SimplexSolution solve(const Eigen::Ref<const Eigen::VectorXd>& b) const;

 private:
  int mShapeCount = 0;
  int mRowCount = 0;
  double mLambda = 0.0;
  Eigen::MatrixXd mZ;       // k by k-1
  Eigen::MatrixXd mBasis;   // n by k-1
  Eigen::VectorXd mCenter;  // n
  Eigen::MatrixXd mR;       // k-1 by k-1, upper triangular
  Eigen::MatrixXd mC;       // k-1 by 2k: normals of the bounds w_i >= l_i, -w_i >= -u_i in y
};

}  // namespace drivenshape
