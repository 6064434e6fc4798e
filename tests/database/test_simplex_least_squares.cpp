// SPDX-License-Identifier: Apache-2.0
// Tests for SimplexLeastSquares (blend weights: min |A w - b|^2, sum w = 1, 0 <= w <= 1):
// more than 1,000 problems of every shape the bake meets, each compared with an independent
// reference that enumerates which weights are free, at 0 or at 1.

#include <drivenshape/error.h>

#include "qp.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "test_support.h"

namespace drivenshape {
namespace {

using ::drivenshape::testing::kQpConstraintTol;
using ::drivenshape::testing::kQpObjectiveRelTol;
using ::drivenshape::testing::testSeed;

// ---- Independent reference. ----

struct Reference {
  double objective = std::numeric_limits<double>::infinity();
  Eigen::VectorXd weights;
};

/// Enumerates the (free, at 0, at 1) patterns of the weights. A pattern with two weights at 1
/// is infeasible (the others would have to sum to -1), and one with a weight at 1 forces every
/// other weight to 0, which is the pattern "that weight alone free"; so the 3^k patterns reduce
/// to the 2^k - 1 non-empty free sets F with the rest at 0. For each F = {f_1..f_m} the
/// equality-constrained least squares
///
///     w_F = e_{f_m} + sum_{i<m} v_i (e_{f_i} - e_{f_m})     (sum w = 1 for every v)
///     A w - b = B v - (b - a_{f_m}),   B = [a_{f_i} - a_{f_m}]
///
/// is solved with a complete orthogonal decomposition (the minimum-norm v when B is rank
/// deficient). Patterns whose weights leave [0, 1] are dropped; the smallest objective wins.
/// If the optimum is reached by a rank-deficient F, it is also reached by a smaller F with
/// independent columns, which the enumeration visits, so the minimum-norm choice loses nothing.
Reference enumeratePatterns(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  constexpr double kFeasibleSlack = 1e-10;
  const auto k = static_cast<int>(A.cols());
  Reference best;
  for (unsigned mask = 1; mask < (1u << k); ++mask) {
    std::vector<int> free;
    for (int i = 0; i < k; ++i) {
      if (mask & (1u << i)) {
        free.push_back(i);
      }
    }
    const int last = free.back();
    const auto m = static_cast<int>(free.size());
    Eigen::MatrixXd B(A.rows(), m - 1);
    for (int i = 0; i + 1 < m; ++i) {
      B.col(i) = A.col(free[i]) - A.col(last);
    }
    const Eigen::VectorXd target = b - A.col(last);
    Eigen::VectorXd v = Eigen::VectorXd::Zero(m - 1);
    if (m > 1) {
      v = Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(B).solve(target);
    }
    Eigen::VectorXd w = Eigen::VectorXd::Zero(k);
    w(last) = 1.0 - v.sum();
    for (int i = 0; i + 1 < m; ++i) {
      w(free[i]) = v(i);
    }
    if (w.minCoeff() < -kFeasibleSlack || w.maxCoeff() > 1.0 + kFeasibleSlack) {
      continue;
    }
    const double objective = (B * v - target).squaredNorm();
    if (objective < best.objective) {
      best.objective = objective;
      best.weights = w;
    }
  }
  return best;
}

// ---- Problem generators. ----

using Rng = std::mt19937;

Eigen::MatrixXd gaussian(Rng& rng, int rows, int cols, double sigma = 1.0) {
  std::normal_distribution<double> normal(0.0, sigma);
  return Eigen::MatrixXd::NullaryExpr(rows, cols, [&] { return normal(rng); });
}

int uniformInt(Rng& rng, int lo, int hi) {
  return std::uniform_int_distribution<int>(lo, hi)(rng);
}

/// Random weights on the simplex (some exactly zero when `sparse`).
Eigen::VectorXd simplexPoint(Rng& rng, int k, bool sparse) {
  std::exponential_distribution<double> exponential(1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  Eigen::VectorXd w(k);
  for (int i = 0; i < k; ++i) {
    w(i) = sparse && uniform(rng) < 0.5 ? 0.0 : exponential(rng);
  }
  if (w.sum() == 0.0) {
    w(uniformInt(rng, 0, k - 1)) = 1.0;
  }
  return w / w.sum();
}

/// A target pose for database A: a random mix of inside the hull (zero residual), near it,
/// random, and far outside.
Eigen::VectorXd randomTarget(Rng& rng, const Eigen::MatrixXd& A) {
  const auto k = static_cast<int>(A.cols());
  const auto n = static_cast<int>(A.rows());
  const Eigen::VectorXd inside = A * simplexPoint(rng, k, uniformInt(rng, 0, 1) == 1);
  const double spread = std::max(
      (A.colwise() - A.rowwise().mean()).norm() / std::sqrt(static_cast<double>(k * n)), 1e-3);
  switch (uniformInt(rng, 0, 3)) {
    case 0:
      return inside;
    case 1:
      return inside + gaussian(rng, n, 1, 0.3 * spread);
    case 2:
      return A.rowwise().mean() + gaussian(rng, n, 1, 2.0 * spread);
    default:
      return inside + gaussian(rng, n, 1, 50.0 * spread);
  }
}

struct Stats {
  int problems = 0;
  double worstObjective = 0.0;  // |objective - reference| / max(|b|^2, tiny)
  double worstDirect = 0.0;     // |objective - |A w - b|^2| / max(|b|^2, tiny)
  double worstCentered = 0.0;   // |objective - reference| / max(|b - m|^2, tiny)
  double worstSum = 0.0;
  double worstBound = 0.0;
  double worstKkt = 0.0;
  std::map<std::string, int> perCategory;
};

/// Solves one problem and checks it against the reference; returns the solution.
SimplexSolution check(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                      const std::string& category, Stats& stats) {
  const SimplexLeastSquares solver(A);
  const SimplexSolution solution = solver.solve(b);
  const Reference reference = enumeratePatterns(A, b);
  const double scale = std::max(b.squaredNorm(), std::numeric_limits<double>::min());
  const Eigen::VectorXd& w = solution.weights;
  const double direct = (A * w - b).squaredNorm();
  const double objectiveError = std::abs(solution.objective - reference.objective) / scale;
  // The same error against the spread of the problem rather than the size of b: |b|^2 is huge
  // when the shapes sit far from the origin, which must not hide a loss of precision.
  const double centeredScale =
      std::max((b - A.rowwise().mean()).squaredNorm(), std::numeric_limits<double>::min());
  const double centeredError = std::abs(solution.objective - reference.objective) / centeredScale;
  const double directError = std::abs(direct - solution.objective) / scale;
  const double sumError = std::abs(w.sum() - 1.0);
  const double boundError = std::max({0.0, -w.minCoeff(), w.maxCoeff() - 1.0});
  stats.worstObjective = std::max(stats.worstObjective, objectiveError);
  stats.worstDirect = std::max(stats.worstDirect, directError);
  stats.worstCentered = std::max(stats.worstCentered, centeredError);
  stats.worstSum = std::max(stats.worstSum, sumError);
  stats.worstBound = std::max(stats.worstBound, boundError);
  stats.worstKkt = std::max(stats.worstKkt, solution.kktResidual);
  ++stats.problems;
  ++stats.perCategory[category];

  const std::string where = category + " problem (n = " + std::to_string(A.rows()) +
                            ", k = " + std::to_string(A.cols()) + ")";
  EXPECT_EQ(w.size(), A.cols()) << where;
  EXPECT_LE(objectiveError, kQpObjectiveRelTol)
      << where << ": objective " << solution.objective << ", reference " << reference.objective
      << ", |b|^2 " << b.squaredNorm() << "\nweights   " << w.transpose() << "\nreference "
      << reference.weights.transpose();
  EXPECT_LE(directError, kQpObjectiveRelTol) << where << ": |A w - b|^2 = " << direct;
  EXPECT_LE(centeredError, kQpObjectiveRelTol) << where << ": relative to |b - m|^2";
  EXPECT_LE(sumError, kQpConstraintTol) << where;
  EXPECT_LE(boundError, kQpConstraintTol) << where;
  EXPECT_NEAR(solution.sumError, sumError, kQpConstraintTol) << where;
  EXPECT_NEAR(solution.relativeResidual * solution.relativeResidual * b.squaredNorm(),
              solution.objective, kQpObjectiveRelTol * scale)
      << where;
  for (const int i : solution.atZero) {
    EXPECT_EQ(w(i), 0.0) << where;
  }
  for (const int i : solution.atOne) {
    EXPECT_EQ(w(i), 1.0) << where;
  }
  return solution;
}

/// Duplicates some columns of A exactly (copies of other shapes in the database).
void duplicateColumns(Rng& rng, Eigen::MatrixXd& A) {
  const auto k = static_cast<int>(A.cols());
  const int copies = uniformInt(rng, 1, std::max(1, k / 2));
  for (int c = 0; c < copies; ++c) {
    const int to = uniformInt(rng, 1, k - 1);
    A.col(to) = A.col(uniformInt(rng, 0, to - 1));
  }
}

TEST(SimplexLeastSquares, AgreesWithEnumeration) {
  const std::uint32_t seed = testSeed();
  Rng rng(seed);
  Stats stats;
  double oneHotError = 0.0;

  for (int i = 0; i < 450; ++i) {  // random A, n in 3..60, k in 1..8
    const int k = uniformInt(rng, 1, 8);
    const Eigen::MatrixXd A = gaussian(rng, uniformInt(rng, 3, 60), k);
    check(A, randomTarget(rng, A), "random", stats);
  }
  for (int i = 0; i < 120; ++i) {  // rank deficient: more shapes than rows
    const int n = uniformInt(rng, 3, 6);
    const Eigen::MatrixXd A = gaussian(rng, n, uniformInt(rng, n + 1, 8));
    check(A, randomTarget(rng, A), "k > n", stats);
  }
  for (int i = 0; i < 120; ++i) {  // rank deficient: duplicate shapes
    Eigen::MatrixXd A = gaussian(rng, uniformInt(rng, 3, 60), uniformInt(rng, 2, 8));
    duplicateColumns(rng, A);
    check(A, randomTarget(rng, A), "duplicates", stats);
  }
  for (int i = 0; i < 40; ++i) {  // a single shape
    const Eigen::MatrixXd A = gaussian(rng, uniformInt(rng, 3, 60), 1);
    const SimplexSolution s = check(A, randomTarget(rng, A), "k = 1", stats);
    EXPECT_EQ(s.weights(0), 1.0);
  }
  for (int i = 0; i < 100; ++i) {  // b is a shape: objective 0, one-hot for distinct shapes
    const int n = uniformInt(rng, 9, 60);
    const int k = uniformInt(rng, 2, 8);
    const Eigen::MatrixXd A = gaussian(rng, n, k);
    const int column = uniformInt(rng, 0, k - 1);
    const SimplexSolution s = check(A, A.col(column), "b = shape", stats);
    EXPECT_LE(s.objective, kQpObjectiveRelTol * A.col(column).squaredNorm());
    // Generic shapes with k <= n are affinely independent, so the weights are one-hot.
    Eigen::VectorXd oneHot = Eigen::VectorXd::Zero(k);
    oneHot(column) = 1.0;
    oneHotError = std::max(oneHotError, (s.weights - oneHot).cwiseAbs().maxCoeff());
  }
  for (int i = 0; i < 100; ++i) {  // b far outside the hull
    const int k = uniformInt(rng, 2, 8);
    const Eigen::MatrixXd A = gaussian(rng, uniformInt(rng, 3, 60), k);
    const Eigen::VectorXd b = A.rowwise().mean() + gaussian(rng, A.rows(), 1, 1e3);
    check(A, b, "far outside", stats);
  }
  for (int i = 0; i < 100; ++i) {  // b inside the hull: zero residual
    const int k = uniformInt(rng, 2, 8);
    const Eigen::MatrixXd A = gaussian(rng, uniformInt(rng, 3, 60), k);
    const Eigen::VectorXd b = A * simplexPoint(rng, k, i % 2 == 0);
    const SimplexSolution s = check(A, b, "inside", stats);
    EXPECT_LE(s.objective, kQpObjectiveRelTol * b.squaredNorm());
  }
  for (int i = 0; i < 120; ++i) {  // world positions: a common offset 1000 units away
    const int vertices = uniformInt(rng, 1, 20);
    const int k = uniformInt(rng, 2, 8);
    Eigen::MatrixXd A = gaussian(rng, 3 * vertices, k, 0.5);
    for (int v = 0; v < vertices; ++v) {
      A.middleRows(3 * v, 3).colwise() += Eigen::Vector3d(1000.0, -700.0, 300.0);
    }
    if (i % 3 == 0) {
      duplicateColumns(rng, A);
    }
    check(A, randomTarget(rng, A), "offset 1000", stats);
  }

  for (const auto& [category, count] : stats.perCategory) {
    std::printf("[ problems ] %-12s %d\n", category.c_str(), count);
  }
  std::printf(
      "[ measured ] %d problems: worst |objective - reference| / |b|^2 = %.3g, worst "
      "|objective - |Aw-b|^2| / |b|^2 = %.3g, worst |objective - reference| / |b - m|^2 = "
      "%.3g (tolerance %.3g); worst |sum w - 1| = %.3g, worst "
      "bound violation = %.3g (tolerance %.3g); worst relative KKT residual %.3g; worst "
      "distance from one-hot for b = shape %.3g\n",
      stats.problems, stats.worstObjective, stats.worstDirect, stats.worstCentered,
      kQpObjectiveRelTol, stats.worstSum, stats.worstBound, kQpConstraintTol, stats.worstKkt,
      oneHotError);
  EXPECT_GE(stats.problems, 1000);
  // b = shape: the weights are one-hot up to the ridge's pull towards the uniform weights,
  // which is of the order of ridge * cond(M)^2; the objective (checked above) is what counts,
  // and it bounds this distance by sqrt(kQpObjectiveRelTol |b|^2) / sigma_min(M).
  EXPECT_LE(oneHotError, std::sqrt(kQpObjectiveRelTol));
}

// ---- Specific cases. ----

TEST(SimplexLeastSquares, SingleShape) {
  const Eigen::MatrixXd A = (Eigen::MatrixXd(3, 1) << 1.0, 2.0, 3.0).finished();
  const Eigen::VectorXd b = (Eigen::VectorXd(3) << 1.0, 0.0, 0.0).finished();
  const SimplexSolution s = SimplexLeastSquares(A).solve(b);
  ASSERT_EQ(s.weights.size(), 1);
  EXPECT_EQ(s.weights(0), 1.0);
  EXPECT_DOUBLE_EQ(s.objective, 13.0);
  EXPECT_DOUBLE_EQ(s.relativeResidual, std::sqrt(13.0));
  EXPECT_EQ(s.atOne, std::vector<int>{0});
}

TEST(SimplexLeastSquares, TwoShapesOneHot) {
  // b beyond shape 1 on the line through both shapes: w = (0, 1) exactly, a case where the
  // tight bounds w_0 >= 0 and w_1 <= 1 are dependent.
  const Eigen::MatrixXd A = (Eigen::MatrixXd(3, 2) << 0.0, 1.0, 0.0, 0.0, 0.0, 0.0).finished();
  for (const double x : {3.0, 1.0 + 1e-9, 1e6}) {
    const Eigen::VectorXd b = (Eigen::VectorXd(3) << x, 0.0, 0.0).finished();
    const SimplexSolution s = SimplexLeastSquares(A).solve(b);
    EXPECT_EQ(s.weights(0), 0.0) << x;
    EXPECT_EQ(s.weights(1), 1.0) << x;
    EXPECT_EQ(s.atZero, std::vector<int>{0}) << x;
    EXPECT_EQ(s.atOne, std::vector<int>{1}) << x;
    EXPECT_NEAR(s.objective, (x - 1.0) * (x - 1.0), kQpObjectiveRelTol * x * x) << x;
  }
  // And between them: free weights, nothing at a bound.
  const Eigen::VectorXd b = (Eigen::VectorXd(3) << 0.25, 1.0, 0.0).finished();
  const SimplexSolution s = SimplexLeastSquares(A).solve(b);
  EXPECT_NEAR(s.weights(0), 0.75, 1e-12);
  EXPECT_NEAR(s.weights(1), 0.25, 1e-12);
  EXPECT_TRUE(s.atZero.empty());
  EXPECT_TRUE(s.atOne.empty());
  EXPECT_NEAR(s.objective, 1.0, kQpObjectiveRelTol);
}

TEST(SimplexLeastSquares, IdenticalShapes) {
  Rng rng(testSeed());
  // Any weights are optimal. With k = 5 the mean shape rounds, so M is rounding noise: the
  // weights may be anything feasible, the objective must still be right.
  const Eigen::VectorXd shape = gaussian(rng, 12, 1);
  const Eigen::VectorXd b = gaussian(rng, 12, 1);
  SimplexSolution s = SimplexLeastSquares(shape.replicate(1, 5)).solve(b);
  EXPECT_LE(std::abs(s.weights.sum() - 1.0), kQpConstraintTol);
  EXPECT_GE(s.weights.minCoeff(), 0.0);
  EXPECT_NEAR(s.objective, (shape - b).squaredNorm(), kQpObjectiveRelTol * b.squaredNorm());
  // With k = 4 and integer positions the mean is exact, M = 0, and the ridge alone picks the
  // uniform weights.
  const Eigen::VectorXd integral = (4.0 * shape).array().round();
  s = SimplexLeastSquares(integral.replicate(1, 4)).solve(b);
  EXPECT_EQ(s.weights, Eigen::VectorXd::Constant(4, 0.25));
  EXPECT_NEAR(s.objective, (integral - b).squaredNorm(), kQpObjectiveRelTol * b.squaredNorm());
}

TEST(SimplexLeastSquares, BasisAndCenter) {
  Rng rng(testSeed());
  Eigen::MatrixXd A = gaussian(rng, 30, 6);
  A.array() += 1000.0;
  const SimplexLeastSquares solver(A);
  EXPECT_EQ(solver.shapeCount(), 6);
  EXPECT_EQ(solver.rowCount(), 30);
  EXPECT_LE((solver.center() - A.rowwise().mean()).cwiseAbs().maxCoeff(), 1e-12);
  // M = (A - m 1^T) Z with Z orthonormal and orthogonal to 1: M M^T = (A - m 1^T)(A - m 1^T)^T.
  const Eigen::MatrixXd centered = A.colwise() - A.rowwise().mean();
  const Eigen::MatrixXd& M = solver.basis();
  ASSERT_EQ(M.rows(), 30);
  ASSERT_EQ(M.cols(), 5);
  EXPECT_LE((M * M.transpose() - centered * centered.transpose()).cwiseAbs().maxCoeff(),
            1e-12 * centered.squaredNorm());
  // solve(b) is solveProjected of the host projection.
  const Eigen::VectorXd b = A * simplexPoint(rng, 6, false) + gaussian(rng, 30, 1);
  const SimplexSolution direct = solver.solve(b);
  const SimplexSolution projected = solver.solveProjected(
      M.transpose() * (b - solver.center()), (b - solver.center()).squaredNorm(), b.squaredNorm());
  EXPECT_EQ(direct.weights, projected.weights);
}

TEST(SimplexLeastSquares, FloatProjectionStillPassesChecks) {
  // The bake computes p, rr and bb in float on the device; the checks are made relative to the
  // given projection, so rounding it must not trip them.
  Rng rng(testSeed());
  double worst = 0.0;
  for (int i = 0; i < 50; ++i) {
    const int k = uniformInt(rng, 2, 12);
    Eigen::MatrixXd A = gaussian(rng, 60, k, 0.1);
    A.array() += 50.0;
    if (i % 2 == 0) {
      duplicateColumns(rng, A);
    }
    const SimplexLeastSquares solver(A);
    const Eigen::VectorXd b = randomTarget(rng, A);
    const Eigen::VectorXd r = b - solver.center();
    const Eigen::VectorXd p = (solver.basis().transpose() * r).cast<float>().cast<double>();
    const double rr = static_cast<float>(r.squaredNorm());
    const double bb = static_cast<float>(b.squaredNorm());
    const SimplexSolution s = solver.solveProjected(p, rr, bb);
    const SimplexSolution exact = solver.solve(b);
    EXPECT_LE(std::abs(s.weights.sum() - 1.0), kQpConstraintTol);
    worst = std::max(worst, std::abs((A * s.weights - b).squaredNorm() - exact.objective) / bb);
  }
  std::printf("[ measured ] float projection: worst objective change / |b|^2 = %.3g\n", worst);
  EXPECT_LE(worst, 1e-5);  // float rounding of p and rr, not a QP tolerance
}

TEST(SimplexLeastSquares, BadInputThrows) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Ones(6, 3);
  A(4, 2) = std::numeric_limits<double>::quiet_NaN();
  ::drivenshape::testing::expectThrows([&] { SimplexLeastSquares solver(A); },
                                       ErrorCode::kNumerical, "shape 2");
  ::drivenshape::testing::expectThrows([&] { SimplexLeastSquares solver(A); },
                                       ErrorCode::kNumerical, "vertex 1");
  A(4, 2) = 1.0;
  ::drivenshape::testing::expectThrows([&] { SimplexLeastSquares solver(Eigen::MatrixXd(6, 0)); },
                                       ErrorCode::kInput, "at least one");
  ::drivenshape::testing::expectThrows([&] { SimplexLeastSquares solver(A, 0.0); },
                                       ErrorCode::kUsage, "ridge");

  const SimplexLeastSquares solver(A);
  Eigen::VectorXd b = Eigen::VectorXd::Ones(6);
  b(3) = std::numeric_limits<double>::infinity();
  ::drivenshape::testing::expectThrows([&] { solver.solve(b); }, ErrorCode::kNumerical, "row 3");
  ::drivenshape::testing::expectThrows([&] { solver.solve(Eigen::VectorXd::Ones(5)); },
                                       ErrorCode::kInternal, "6 expected");
  Eigen::VectorXd p = Eigen::VectorXd::Zero(2);
  p(1) = std::numeric_limits<double>::quiet_NaN();
  ::drivenshape::testing::expectThrows([&] { solver.solveProjected(p, 1.0, 1.0); },
                                       ErrorCode::kNumerical, "projection entry 1");
  ::drivenshape::testing::expectThrows(
      [&] { solver.solveProjected(Eigen::VectorXd::Zero(3), 1.0, 1.0); }, ErrorCode::kInternal,
      "2 expected");
  ::drivenshape::testing::expectThrows(
      [&] {
        solver.solveProjected(Eigen::VectorXd::Zero(2), std::numeric_limits<double>::infinity(),
                              1.0);
      },
      ErrorCode::kNumerical, "|b - m|^2");
}

// ---- Per-shape bounds (temporal stability): lower_i <= w_i <= upper_i. ----

/// The box version of enumeratePatterns: each weight is free, at its lower or at its upper
/// bound (3^k patterns). For the held weights H and free weights F = {f_1..f_m}, with
/// s = 1 - sum(w_H):
///
///     w_F = s e_{f_m} + sum_{i<m} v_i (e_{f_i} - e_{f_m})
///     A w - b = B v - (b - A_H w_H - s a_{f_m}),   B = [a_{f_i} - a_{f_m}]
///
/// solved with a complete orthogonal decomposition as above; patterns whose weights leave the
/// box are dropped, and an empty F counts only when the held weights sum to 1. As for [0, 1],
/// an optimum reached by a rank-deficient F is also reached by a smaller F (move along the null
/// direction until a weight meets a bound), so the minimum-norm choice loses nothing.
Reference enumerateBoxPatterns(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                               const Eigen::VectorXd& lower, const Eigen::VectorXd& upper) {
  constexpr double kFeasibleSlack = 1e-10;
  const auto k = static_cast<int>(A.cols());
  int patterns = 1;
  for (int i = 0; i < k; ++i) {
    patterns *= 3;
  }
  Reference best;
  for (int code = 0; code < patterns; ++code) {
    std::vector<int> free;
    Eigen::VectorXd w = Eigen::VectorXd::Zero(k);
    double heldSum = 0.0;
    for (int i = 0, rest = code; i < k; ++i, rest /= 3) {
      if (rest % 3 == 0) {
        free.push_back(i);
      } else {
        w(i) = rest % 3 == 1 ? lower(i) : upper(i);
        heldSum += w(i);
      }
    }
    const double share = 1.0 - heldSum;
    if (free.empty()) {
      if (std::abs(share) > kFeasibleSlack) {
        continue;
      }
    } else {
      const int last = free.back();
      const auto m = static_cast<int>(free.size());
      Eigen::MatrixXd B(A.rows(), m - 1);
      for (int i = 0; i + 1 < m; ++i) {
        B.col(i) = A.col(free[i]) - A.col(last);
      }
      const Eigen::VectorXd target = b - A * w - share * A.col(last);
      Eigen::VectorXd v = Eigen::VectorXd::Zero(m - 1);
      if (m > 1) {
        v = Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(B).solve(target);
      }
      w(last) = share - v.sum();
      for (int i = 0; i + 1 < m; ++i) {
        w(free[i]) = v(i);
      }
    }
    if ((w - lower).minCoeff() < -kFeasibleSlack || (upper - w).minCoeff() < -kFeasibleSlack) {
      continue;
    }
    const double objective = (A * w - b).squaredNorm();
    if (objective < best.objective) {
      best.objective = objective;
      best.weights = w;
    }
  }
  return best;
}

struct Box {
  Eigen::VectorXd lower;
  Eigen::VectorXd upper;
};

/// A box around a random point of the simplex (the previous frame's weights): per shape a
/// half-width below and above drawn from {0, tiny, small, medium, large} (0 fixes the weight),
/// intersected with [0, 1]. The centre is inside, so the preconditions hold.
Box randomBox(Rng& rng, int k) {
  const Eigen::VectorXd centre = simplexPoint(rng, k, uniformInt(rng, 0, 1) == 1);
  const double widths[] = {0.0, 1e-9, 0.02, 0.1, 0.4, 2.0};
  const bool uniform = uniformInt(rng, 0, 1) == 1;  // one tau for all (the bake's use)
  const double tau = widths[uniformInt(rng, 1, 5)];
  Box box{Eigen::VectorXd(k), Eigen::VectorXd(k)};
  for (int i = 0; i < k; ++i) {
    const double below = uniform ? tau : widths[uniformInt(rng, 0, 5)];
    const double above = uniform ? tau : widths[uniformInt(rng, 0, 5)];
    box.lower(i) = std::max(0.0, centre(i) - below);
    box.upper(i) = std::min(1.0, centre(i) + above);
  }
  return box;
}

TEST(SimplexLeastSquaresBounded, AgreesWithEnumeration) {
  const std::uint32_t seed = testSeed();
  Rng rng(seed);
  int problems = 0;
  double worstObjective = 0.0, worstSum = 0.0, worstBound = 0.0, worstKkt = 0.0;
  int heldAtLower = 0, heldAtUpper = 0, fixedWeights = 0;
  for (int i = 0; i < 900; ++i) {
    const int k = uniformInt(rng, 1, 7);
    Eigen::MatrixXd A = gaussian(rng, uniformInt(rng, 3, 40), k);
    const int kind = i % 4;
    if (kind == 1 && k > 1) {
      duplicateColumns(rng, A);
    } else if (kind == 2) {
      A.array() += 1000.0;  // world positions far from the origin
    }
    const Eigen::VectorXd b =
        kind == 3 ? Eigen::VectorXd(gaussian(rng, A.rows(), 1, 1e3)) : randomTarget(rng, A);
    const Box box = randomBox(rng, k);
    const std::string where = "bounded problem " + std::to_string(i) +
                              " (n = " + std::to_string(A.rows()) + ", k = " + std::to_string(k) +
                              ")";
    const SimplexLeastSquares solver(A);
    const Eigen::VectorXd r = b - solver.center();
    const SimplexSolution s = solver.solveProjected(solver.basis().transpose() * r, r.squaredNorm(),
                                                    b.squaredNorm(), box.lower, box.upper);
    const Reference reference = enumerateBoxPatterns(A, b, box.lower, box.upper);
    ASSERT_TRUE(std::isfinite(reference.objective)) << where << ": no feasible pattern";
    const Eigen::VectorXd& w = s.weights;
    ASSERT_EQ(w.size(), k) << where;
    const double scale = std::max(b.squaredNorm(), std::numeric_limits<double>::min());
    const double objectiveError = std::abs(s.objective - reference.objective) / scale;
    const double directError = std::abs((A * w - b).squaredNorm() - s.objective) / scale;
    const double sumError = std::abs(w.sum() - 1.0);
    const double boundError =
        std::max({0.0, (box.lower - w).maxCoeff(), (w - box.upper).maxCoeff()});
    worstObjective = std::max({worstObjective, objectiveError, directError});
    worstSum = std::max(worstSum, sumError);
    worstBound = std::max(worstBound, boundError);
    worstKkt = std::max(worstKkt, s.kktResidual);
    EXPECT_LE(objectiveError, kQpObjectiveRelTol)
        << where << ": objective " << s.objective << ", reference " << reference.objective
        << "\nweights   " << w.transpose() << "\nreference " << reference.weights.transpose()
        << "\nlower     " << box.lower.transpose() << "\nupper     " << box.upper.transpose();
    EXPECT_LE(directError, kQpObjectiveRelTol) << where;
    EXPECT_LE(sumError, kQpConstraintTol) << where;
    EXPECT_LE(boundError, kQpConstraintTol) << where;
    for (const int j : s.atZero) {
      EXPECT_EQ(w(j), box.lower(j)) << where << ", shape " << j;
    }
    for (const int j : s.atOne) {
      EXPECT_EQ(w(j), box.upper(j)) << where << ", shape " << j;
    }
    for (int j = 0; j < k; ++j) {
      if (box.lower(j) == box.upper(j)) {
        EXPECT_EQ(w(j), box.lower(j)) << where << ": shape " << j << " is fixed by its box";
        ++fixedWeights;
      }
    }
    heldAtLower += static_cast<int>(s.atZero.size());
    heldAtUpper += static_cast<int>(s.atOne.size());
    ++problems;
  }
  std::printf(
      "[ measured ] %d bounded problems (%d weights fixed by their box, %d held at lower, %d at "
      "upper): worst objective error / |b|^2 = %.3g (tolerance %.3g), worst |sum w - 1| = %.3g, "
      "worst box violation = %.3g (tolerance %.3g), worst relative KKT residual %.3g\n",
      problems, fixedWeights, heldAtLower, heldAtUpper, worstObjective, kQpObjectiveRelTol,
      worstSum, worstBound, kQpConstraintTol, worstKkt);
  // The generator must reach the cases that matter: weights pinned and held at both bounds.
  EXPECT_GT(fixedWeights, 50);
  EXPECT_GT(heldAtUpper, 100);
}

TEST(SimplexLeastSquaresBounded, UnitBoxIsBitwiseTheUnboundedSolve) {
  Rng rng(testSeed());
  int problems = 0;
  for (int i = 0; i < 600; ++i) {
    const int k = uniformInt(rng, 1, 12);
    Eigen::MatrixXd A = gaussian(rng, uniformInt(rng, 3, 60), k);
    if (i % 3 == 1 && k > 1) {
      duplicateColumns(rng, A);
    } else if (i % 3 == 2) {
      A.array() += 1000.0;
    }
    const Eigen::VectorXd b = randomTarget(rng, A);
    const SimplexLeastSquares solver(A);
    const Eigen::VectorXd r = b - solver.center();
    const Eigen::VectorXd p = solver.basis().transpose() * r;
    const SimplexSolution plain = solver.solveProjected(p, r.squaredNorm(), b.squaredNorm());
    const SimplexSolution boxed = solver.solveProjected(
        p, r.squaredNorm(), b.squaredNorm(), Eigen::VectorXd::Zero(k), Eigen::VectorXd::Ones(k));
    ASSERT_EQ(plain.weights.size(), boxed.weights.size());
    for (int j = 0; j < k; ++j) {
      // Bitwise: the same doubles, not merely close.
      EXPECT_EQ(plain.weights(j), boxed.weights(j)) << "problem " << i << ", shape " << j;
    }
    EXPECT_EQ(plain.atZero, boxed.atZero) << "problem " << i;
    EXPECT_EQ(plain.atOne, boxed.atOne) << "problem " << i;
    EXPECT_EQ(plain.objective, boxed.objective) << "problem " << i;
    EXPECT_EQ(plain.kktResidual, boxed.kktResidual) << "problem " << i;
    EXPECT_EQ(plain.iterations, boxed.iterations) << "problem " << i;
    ++problems;
  }
  std::printf("[ measured ] %d problems: [0, 1] boxes bitwise equal to the plain solve\n",
              problems);
}

TEST(SimplexLeastSquaresBounded, PinnedBoxReturnsItsCorner) {
  Rng rng(testSeed());
  const Eigen::MatrixXd A = gaussian(rng, 30, 6);
  const SimplexLeastSquares solver(A);
  const Eigen::VectorXd b = gaussian(rng, 30, 1);
  const Eigen::VectorXd r = b - solver.center();
  const Eigen::VectorXd p = solver.basis().transpose() * r;
  // tau = 0: the previous weights themselves.
  const Eigen::VectorXd previous = simplexPoint(rng, 6, true);
  const SimplexSolution s =
      solver.solveProjected(p, r.squaredNorm(), b.squaredNorm(), previous, previous);
  EXPECT_EQ(s.weights, previous);
  EXPECT_EQ(s.kktResidual, 0.0);
  EXPECT_NEAR(s.objective, (A * previous - b).squaredNorm(), kQpObjectiveRelTol * b.squaredNorm());
  // Upper corner summing to 1 with the lower bounds below it.
  const SimplexSolution high = solver.solveProjected(p, r.squaredNorm(), b.squaredNorm(),
                                                     Eigen::VectorXd::Zero(6), previous);
  EXPECT_EQ(high.weights, previous);
}

TEST(SimplexLeastSquaresBounded, ConsecutiveFramesStayWithinTau) {
  // The use in a bake: each frame's weights within tau of the previous frame's. A pose that
  // jumps from near shape 0 to near shape 3 makes the free weights jump; the bounded ones move
  // at most tau per frame and reach the free optimum after a few frames.
  Rng rng(testSeed());
  const int k = 5;
  const Eigen::MatrixXd A = gaussian(rng, 45, k);
  const SimplexLeastSquares solver(A);
  const double tau = 0.1;
  Eigen::VectorXd previous = solver.solve(A.col(0)).weights;
  const Eigen::VectorXd b = A.col(3);
  const SimplexSolution free = solver.solve(b);
  const Eigen::VectorXd r = b - solver.center();
  const Eigen::VectorXd p = solver.basis().transpose() * r;
  int frames = 0;
  while ((previous - free.weights).cwiseAbs().maxCoeff() > 1e-9 && frames < 100) {
    const Eigen::VectorXd lower = (previous.array() - tau).max(0.0);
    const Eigen::VectorXd upper = (previous.array() + tau).min(1.0);
    const SimplexSolution s =
        solver.solveProjected(p, r.squaredNorm(), b.squaredNorm(), lower, upper);
    EXPECT_LE((s.weights - previous).cwiseAbs().maxCoeff(), tau + kQpConstraintTol)
        << "frame " << frames;
    EXPECT_GE(s.objective, free.objective * (1.0 - kQpObjectiveRelTol) - kQpObjectiveRelTol);
    previous = s.weights;
    ++frames;
  }
  // Weight 0 goes from 1 to 0 and weight 3 from 0 to 1: at least 1 / tau frames.
  EXPECT_GE(frames, 10);
  EXPECT_LT(frames, 100) << "the bounded weights never reached the free optimum";
  EXPECT_NEAR(solver
                  .solveProjected(p, r.squaredNorm(), b.squaredNorm(),
                                  (previous.array() - tau).max(0.0).matrix(),
                                  (previous.array() + tau).min(1.0).matrix())
                  .objective,
              free.objective, kQpObjectiveRelTol * b.squaredNorm());
}

TEST(SimplexLeastSquaresBounded, BadBoundsThrowInternal) {
  const Eigen::MatrixXd A =
      (Eigen::MatrixXd(6, 3) << 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 0, 0, 1, 1, 2, 0, 1).finished();
  const SimplexLeastSquares solver(A);
  const Eigen::VectorXd p = Eigen::VectorXd::Zero(2);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(3);
  const Eigen::VectorXd one = Eigen::VectorXd::Ones(3);
  auto call = [&](const Eigen::VectorXd& lower, const Eigen::VectorXd& upper) {
    return [&solver, &p, lower, upper] { solver.solveProjected(p, 1.0, 1.0, lower, upper); };
  };
  ::drivenshape::testing::expectThrows(call(Eigen::VectorXd::Zero(2), one), ErrorCode::kInternal,
                                       "3 expected");
  ::drivenshape::testing::expectThrows(call(zero, Eigen::VectorXd::Ones(4)), ErrorCode::kInternal,
                                       "3 expected");
  ::drivenshape::testing::expectThrows(call(Eigen::Vector3d(-0.1, 0, 0), one), ErrorCode::kInternal,
                                       "shape 0");
  ::drivenshape::testing::expectThrows(call(zero, Eigen::Vector3d(1, 1.5, 1)), ErrorCode::kInternal,
                                       "shape 1");
  ::drivenshape::testing::expectThrows(call(Eigen::Vector3d(0, 0, 0.6), Eigen::Vector3d(1, 1, 0.5)),
                                       ErrorCode::kInternal, "shape 2");
  ::drivenshape::testing::expectThrows(
      call(Eigen::Vector3d(0, std::numeric_limits<double>::quiet_NaN(), 0), one),
      ErrorCode::kInternal, "shape 1");
  ::drivenshape::testing::expectThrows(call(Eigen::Vector3d(0.5, 0.5, 0.5), one),
                                       ErrorCode::kInternal, "no weights");
  ::drivenshape::testing::expectThrows(call(zero, Eigen::Vector3d(0.3, 0.3, 0.3)),
                                       ErrorCode::kInternal, "no weights");
  // The projection is still checked first.
  ::drivenshape::testing::expectThrows(
      [&] { solver.solveProjected(Eigen::VectorXd::Zero(3), 1.0, 1.0, zero, one); },
      ErrorCode::kInternal, "2 expected");
}

}  // namespace
}  // namespace drivenshape
