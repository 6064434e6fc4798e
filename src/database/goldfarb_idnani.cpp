// SPDX-License-Identifier: Apache-2.0
#include "goldfarb_idnani.h"

#include <drivenshape/error.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

// The dual active-set method of Goldfarb and Idnani (1983), written from the paper.
//
// It starts at the unconstrained minimum x = -G^{-1} a, which is dual feasible, and adds one
// violated constraint at a time, keeping the multipliers of the active inequalities >= 0.
// Everything is expressed through
//
//     J = R^{-1} Q            (n by n, so that J J^T = G^{-1} and J^T G J = I)
//     J^T N = [ Ra ]          N: n by q, the normals of the active constraints
//             [ 0  ]          Ra: q by q, upper triangular
//
// Splitting J = [J1 J2] after q columns, for a normal n+ with d = J^T n+:
//
//     z = J2 d2                the primal step direction (G-orthogonal to the active normals)
//     r = Ra^{-1} d1           how the active multipliers change per unit step
//
// Adding a constraint rotates d2 onto its first entry (Givens rotations applied to the columns
// of J); dropping one deletes a column of Ra and restores its triangle with Givens rotations on
// the rows of Ra (and the same columns of J). No matrix is ever refactorised.

namespace drivenshape::detail {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// A constraint n^T x >= b counts as violated when n^T x - b < -kFeasibilityTol (|b| + |n| |x|):
/// far below what matters to any caller, yet above the rounding of the residual itself, so that
/// a constraint that is satisfied in exact arithmetic (for example one that duplicates an
/// active constraint) is not added and dropped again forever.
constexpr double kFeasibilityTol = 1e3 * kEps;

/// A normal counts as linearly dependent on the active normals when the part of J^T n outside
/// their span, |d2|, is below kDependenceTol |J|_F |n|, which bounds the rounding of d2 when it
/// is zero in exact arithmetic.
constexpr double kDependenceTol = 1e3 * kEps;

/// G = [c s; -s c] with G [a; b] = [hypot(a, b); 0].
struct Rotation {
  double c = 1.0;
  double s = 0.0;
};

Rotation rotationZeroing(double a, double b) {
  if (b == 0.0) {
    return {};
  }
  const double h = std::hypot(a, b);
  return {a / h, b / h};
}

/// Columns (i, j) of m become (c m_i + s m_j, -s m_i + c m_j): J' = J G^T, so J'^T v = G J^T v.
void rotateColumns(Eigen::MatrixXd& m, int i, int j, const Rotation& g) {
  for (Eigen::Index row = 0; row < m.rows(); ++row) {
    const double x = m(row, i);
    const double y = m(row, j);
    m(row, i) = g.c * x + g.s * y;
    m(row, j) = -g.s * x + g.c * y;
  }
}

/// Rows (i, j) of m, columns first..last-1, become (c m_i + s m_j, -s m_i + c m_j).
void rotateRows(Eigen::MatrixXd& m, int i, int j, int first, int last, const Rotation& g) {
  for (int col = first; col < last; ++col) {
    const double x = m(i, col);
    const double y = m(j, col);
    m(i, col) = g.c * x + g.s * y;
    m(j, col) = -g.s * x + g.c * y;
  }
}

void checkFinite(const Eigen::Ref<const Eigen::MatrixXd>& m, const char* name) {
  for (Eigen::Index col = 0; col < m.cols(); ++col) {
    for (Eigen::Index row = 0; row < m.rows(); ++row) {
      if (!std::isfinite(m(row, col))) {
        DS_THROW(kNumerical, "Goldfarb-Idnani QP: ", name, "(", row, ", ", col, ") is ",
                 m(row, col), "; every entry of the problem must be finite");
      }
    }
  }
}

class DualActiveSet {
 public:
  DualActiveSet(const Eigen::Ref<const Eigen::MatrixXd>& R,
                const Eigen::Ref<const Eigen::VectorXd>& a,
                const Eigen::Ref<const Eigen::MatrixXd>& E,
                const Eigen::Ref<const Eigen::VectorXd>& e,
                const Eigen::Ref<const Eigen::MatrixXd>& C,
                const Eigen::Ref<const Eigen::VectorXd>& c)
      : mR(R), mA(a), mE(E), mEb(e), mC(C), mCb(c) {}

  QpResult solve();

 private:
  /// Constraint `id` (0..me-1 equalities, me+i inequality i), oriented by `sign`.
  Eigen::VectorXd normal(int id, double sign) const {
    return id < mMe ? Eigen::VectorXd(sign * mE.col(id)) : Eigen::VectorXd(mC.col(id - mMe));
  }
  double bound(int id, double sign) const { return id < mMe ? sign * mEb(id) : mCb(id - mMe); }
  static double feasibilityTol(double b, double normalNorm, double xNorm) {
    return kFeasibilityTol * (std::abs(b) + normalNorm * xNorm);
  }
  double dependenceTol(double normalNorm) const { return kDependenceTol * mJNorm * normalNorm; }

  /// Multipliers of the active set for a unit step along n+: r = Ra^{-1} d1.
  Eigen::VectorXd dualDirection(const Eigen::VectorXd& d) const {
    return mRa.topLeftCorner(mQ, mQ).triangularView<Eigen::Upper>().solve(d.head(mQ));
  }

  /// Error(kInternal) for inconsistent sizes, Error(kNumerical) for a non-finite entry or a
  /// zero on the diagonal of R.
  void checkProblem() const;
  /// J = R^{-1}, no constraint active, x at the unconstrained minimum -G^{-1} a.
  void startUnconstrained();
  /// Makes every equality active (skipping redundant ones); false when they are inconsistent.
  bool addEqualities();
  /// The inactive inequality violated the most, or -1 when x satisfies them all.
  int mostViolatedInequality(const Eigen::VectorXd& normNormals) const;
  /// Adds inequality `chosen`, dropping active ones whose multipliers reach zero first; false
  /// when no multiplier can absorb its normal (the problem is infeasible).
  bool addInequality(int chosen, double normalNorm);
  void addConstraint(Eigen::VectorXd d, int id, double sign, double multiplier);
  void dropConstraint(int position);
  void countIteration();
  double refine();
  void refineUntilSettled();
  QpResult result(bool feasible) const;

  const Eigen::Ref<const Eigen::MatrixXd>& mR;
  const Eigen::Ref<const Eigen::VectorXd>& mA;
  const Eigen::Ref<const Eigen::MatrixXd>& mE;
  const Eigen::Ref<const Eigen::VectorXd>& mEb;
  const Eigen::Ref<const Eigen::MatrixXd>& mC;
  const Eigen::Ref<const Eigen::VectorXd>& mCb;

  int mN = 0;
  int mMe = 0;
  int mMi = 0;
  int mIterations = 0;
  int mIterationCap = 0;
  double mJNorm = 0.0;       // |J|_F, unchanged by the rotations
  Eigen::MatrixXd mJ;        // n by n
  Eigen::MatrixXd mRa;       // n by n, upper-left mQ by mQ used
  int mQ = 0;                // number of active constraints
  std::vector<int> mActive;  // constraint ids, position = column of Ra
  std::vector<double> mSign;
  std::vector<char> mIsActive;  // per inequality
  Eigen::VectorXd mU;           // multipliers of the active constraints (first mQ)
  Eigen::VectorXd mX;
};

void DualActiveSet::countIteration() {
  ++mIterations;
  if (mIterations > mIterationCap) {
    DS_THROW(kNumerical, "Goldfarb-Idnani QP did not converge in ", mIterationCap,
             " iterations (n = ", mN, ", ", mMe, " equalities, ", mMi,
             " inequalities); the problem is too badly conditioned or degenerate");
  }
}

void DualActiveSet::addConstraint(Eigen::VectorXd d, int id, double sign, double multiplier) {
  // Rotate d(q..n-1) onto d(q), bottom up; the rotations touch columns q.. of J only, which
  // are orthogonal to the active normals, so Ra keeps its triangle.
  for (int i = mN - 1; i > mQ; --i) {
    const Rotation g = rotationZeroing(d(i - 1), d(i));
    d(i - 1) = g.c * d(i - 1) + g.s * d(i);
    d(i) = 0.0;
    rotateColumns(mJ, i - 1, i, g);
  }
  mRa.col(mQ).head(mQ + 1) = d.head(mQ + 1);
  mU(mQ) = multiplier;
  mActive.push_back(id);
  mSign.push_back(sign);
  if (id >= mMe) {
    mIsActive[id - mMe] = 1;
  }
  ++mQ;
}

void DualActiveSet::dropConstraint(int position) {
  const int id = mActive[position];
  if (id >= mMe) {
    mIsActive[id - mMe] = 0;
  }
  for (int j = position; j + 1 < mQ; ++j) {
    mRa.col(j).head(mQ) = mRa.col(j + 1).head(mQ);
    mU(j) = mU(j + 1);
  }
  mActive.erase(mActive.begin() + position);
  mSign.erase(mSign.begin() + position);
  // Columns position..q-2 now have one entry below the diagonal (upper Hessenberg).
  for (int j = position; j + 1 < mQ; ++j) {
    const Rotation g = rotationZeroing(mRa(j, j), mRa(j + 1, j));
    rotateRows(mRa, j, j + 1, j, mQ - 1, g);
    mRa(j + 1, j) = 0.0;
    rotateColumns(mJ, j, j + 1, g);
  }
  mRa.col(mQ - 1).setZero();
  mU(mQ - 1) = 0.0;
  --mQ;
}

// One step of iterative refinement on the KKT system of the current active set:
//
//     G dx - N du = N u - G x - a,     N^T dx = b_N - N^T x.
//
// With dx = J [alpha; beta]: Ra^T alpha = b_N - N^T x, beta = (J^T rhs)_2 and
// du = Ra^{-1} (alpha - (J^T rhs)_1). Done after every constraint added: it removes the
// rounding left by long steps (from an unconstrained minimum far from the feasible set, where
// x loses digits to cancellation) before the next constraint is tested against that x.
double DualActiveSet::refine() {
  const int q = mQ;
  Eigen::VectorXd constraintResidual(q);
  Eigen::VectorXd stationarity = -mA;
  stationarity.noalias() -=
      mR.triangularView<Eigen::Upper>().transpose() * (mR.triangularView<Eigen::Upper>() * mX);
  for (int j = 0; j < q; ++j) {
    const Eigen::VectorXd n = normal(mActive[j], mSign[j]);
    constraintResidual(j) = bound(mActive[j], mSign[j]) - n.dot(mX);
    stationarity += mU(j) * n;
  }
  const Eigen::VectorXd h = mJ.transpose() * stationarity;
  const auto Ra = mRa.topLeftCorner(q, q).triangularView<Eigen::Upper>();
  const Eigen::VectorXd alpha = Ra.transpose().solve(constraintResidual);
  const Eigen::VectorXd du = Ra.solve(alpha - h.head(q));
  Eigen::VectorXd dx = mJ.leftCols(q) * alpha;
  dx.noalias() += mJ.rightCols(mN - q) * h.tail(mN - q);
  mX += dx;
  mU.head(q) += du;
  for (int j = 0; j < q; ++j) {
    if (mActive[j] >= mMe) {
      mU(j) = std::max(mU(j), 0.0);  // rounding must not turn a step length negative
    }
  }
  return dx.norm();
}

// A step from very far away (an unconstrained minimum at 1e30 when G is nearly singular) can
// need more than one refinement; stop when x no longer moves or after a few passes.
void DualActiveSet::refineUntilSettled() {
  constexpr int kMaxPasses = 4;
  for (int pass = 0; pass < kMaxPasses; ++pass) {
    if (refine() <= 16.0 * kEps * mX.norm()) {
      return;
    }
  }
}

QpResult DualActiveSet::result(bool feasible) const {
  QpResult out;
  out.x = mX;
  out.objective = 0.5 * (mR.triangularView<Eigen::Upper>() * mX).squaredNorm() + mA.dot(mX);
  out.active = mActive;
  out.multipliers.resize(mQ);
  for (int j = 0; j < mQ; ++j) {
    // Equalities were oriented by mSign; report them for E^T x = e as given. Inequality
    // multipliers are >= 0 by construction; clear the rounding below zero.
    out.multipliers(j) = mActive[j] < mMe ? mSign[j] * mU(j) : std::max(mU(j), 0.0);
  }
  out.iterations = mIterations;
  out.feasible = feasible;
  return out;
}

void DualActiveSet::checkProblem() const {
  if (mR.cols() != mN || mA.size() != mN || (mMe > 0 && mE.rows() != mN) || mEb.size() != mMe ||
      (mMi > 0 && mC.rows() != mN) || mCb.size() != mMi) {
    DS_THROW(kInternal, "Goldfarb-Idnani QP: inconsistent sizes: R ", mR.rows(), "x", mR.cols(),
             ", a ", mA.size(), ", E ", mE.rows(), "x", mE.cols(), ", e ", mEb.size(), ", C ",
             mC.rows(), "x", mC.cols(), ", c ", mCb.size());
  }
  checkFinite(mR, "R");
  checkFinite(mA, "a");
  checkFinite(mE, "E");
  checkFinite(mEb, "e");
  checkFinite(mC, "C");
  checkFinite(mCb, "c");
  for (int i = 0; i < mN; ++i) {
    if (mR(i, i) == 0.0) {
      DS_THROW(kNumerical, "Goldfarb-Idnani QP: R(", i, ", ", i,
               ") is zero; G = R^T R must be positive definite");
    }
  }
}

void DualActiveSet::startUnconstrained() {
  mIterationCap = 10 * (mN + mMe + mMi) + 50;
  mJ = mR.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(mN, mN));
  mJNorm = mJ.norm();
  if (!std::isfinite(mJNorm)) {
    DS_THROW(kNumerical, "Goldfarb-Idnani QP: R is numerically singular (its inverse overflows)");
  }
  mRa = Eigen::MatrixXd::Zero(mN, mN);
  mU = Eigen::VectorXd::Zero(mN);
  mIsActive.assign(mMi, 0);
  mX = -(mJ * (mJ.transpose() * mA));
}

// Equalities first. Each is oriented so that it is a violated (or tight) ">=" constraint;
// no inequality is active yet, so every step is a full step.
bool DualActiveSet::addEqualities() {
  for (int j = 0; j < mMe; ++j) {
    const double residual = mE.col(j).dot(mX) - mEb(j);
    const double sign = residual > 0.0 ? -1.0 : 1.0;
    const Eigen::VectorXd n = normal(j, sign);
    const double normalNorm = n.norm();
    const Eigen::VectorXd d = mJ.transpose() * n;
    const double d2Norm = d.tail(mN - mQ).norm();
    if (d2Norm <= dependenceTol(normalNorm)) {
      // A combination of the equalities already active: redundant if consistent.
      if (std::abs(residual) <= feasibilityTol(mEb(j), normalNorm, mX.norm())) {
        continue;
      }
      return false;
    }
    countIteration();
    const double t = std::abs(residual) / (d2Norm * d2Norm);
    mX.noalias() += t * (mJ.rightCols(mN - mQ) * d.tail(mN - mQ));
    mU.head(mQ) -= t * dualDirection(d);
    addConstraint(d, j, sign, t);
    refineUntilSettled();
  }
  return true;
}

int DualActiveSet::mostViolatedInequality(const Eigen::VectorXd& normNormals) const {
  // Measured as a distance (residual / |normal|).
  int chosen = -1;
  double worst = 0.0;
  const Eigen::VectorXd slack = mC.transpose() * mX - mCb;
  const double xNorm = mX.norm();
  for (int i = 0; i < mMi; ++i) {
    if (mIsActive[i] || slack(i) >= -feasibilityTol(mCb(i), normNormals(i), xNorm)) {
      continue;
    }
    const double distance = normNormals(i) > 0.0 ? slack(i) / normNormals(i) : -kInf;
    if (chosen < 0 || distance < worst) {
      chosen = i;
      worst = distance;
    }
  }
  return chosen;
}

bool DualActiveSet::addInequality(int chosen, double normalNorm) {
  const int id = mMe + chosen;
  const Eigen::VectorXd n = mC.col(chosen);
  double multiplier = 0.0;  // of the constraint being added
  for (;;) {
    const Eigen::VectorXd d = mJ.transpose() * n;
    const double d2Norm = d.tail(mN - mQ).norm();
    const bool dependent = d2Norm <= dependenceTol(normalNorm);
    const Eigen::VectorXd r = dualDirection(d);

    // Partial step: the largest dual step that keeps the active inequality multipliers
    // >= 0; the one that reaches zero first is dropped.
    double partial = kInf;
    int drop = -1;
    for (int j = 0; j < mQ; ++j) {
      if (mActive[j] >= mMe && r(j) > 0.0) {
        const double ratio = mU(j) / r(j);
        if (ratio < partial) {
          partial = ratio;
          drop = j;
        }
      }
    }
    // Full step: the primal step that makes the new constraint tight.
    double full = kInf;
    if (!dependent) {
      full = std::max(-(n.dot(mX) - mCb(chosen)), 0.0) / (d2Norm * d2Norm);
    }
    const double t = std::min(partial, full);
    if (t == kInf) {
      return false;  // no multiplier can absorb the new normal: infeasible
    }
    countIteration();
    if (!dependent) {
      mX.noalias() += t * (mJ.rightCols(mN - mQ) * d.tail(mN - mQ));
    }
    mU.head(mQ) -= t * r;
    multiplier += t;
    if (!dependent && full <= partial) {
      addConstraint(d, id, 1.0, multiplier);
      refineUntilSettled();
      return true;
    }
    mU(drop) = 0.0;
    dropConstraint(drop);
  }
}

QpResult DualActiveSet::solve() {
  mN = static_cast<int>(mR.rows());
  mMe = static_cast<int>(mE.cols());
  mMi = static_cast<int>(mC.cols());
  checkProblem();
  startUnconstrained();
  if (!addEqualities()) {
    return result(false);
  }
  Eigen::VectorXd normNormals(mMi);
  for (int i = 0; i < mMi; ++i) {
    normNormals(i) = mC.col(i).norm();
  }
  for (;;) {
    const int chosen = mostViolatedInequality(normNormals);
    if (chosen < 0) {
      return result(true);
    }
    if (!addInequality(chosen, normNormals(chosen))) {
      return result(false);
    }
  }
}

}  // namespace

QpResult solveGoldfarbIdnani(const Eigen::Ref<const Eigen::MatrixXd>& R,
                             const Eigen::Ref<const Eigen::VectorXd>& a,
                             const Eigen::Ref<const Eigen::MatrixXd>& E,
                             const Eigen::Ref<const Eigen::VectorXd>& e,
                             const Eigen::Ref<const Eigen::MatrixXd>& C,
                             const Eigen::Ref<const Eigen::VectorXd>& c) {
  DualActiveSet solver(R, a, E, e, C, c);
  return solver.solve();
}

}  // namespace drivenshape::detail

namespace drivenshape {

QpResult solveGoldfarbIdnani(const QpProblem& problem) {
  return detail::solveGoldfarbIdnani(problem.R, problem.a, problem.E, problem.e, problem.C,
                                     problem.c);
}

}  // namespace drivenshape
