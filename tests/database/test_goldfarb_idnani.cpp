// SPDX-License-Identifier: Apache-2.0
// Tests for solveGoldfarbIdnani: small problems whose answer can be checked by hand, and random
// strictly convex QPs compared with an independent reference that enumerates active sets.

#include <drivenshape/error.h>

#include "qp.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>

#include "test_support.h"

namespace drivenshape {
namespace {

using ::drivenshape::testing::kQpConstraintTol;
using ::drivenshape::testing::kQpObjectiveRelTol;
using ::drivenshape::testing::testSeed;

Eigen::MatrixXd matrix(int rows, int cols, std::initializer_list<double> rowMajor) {
  Eigen::MatrixXd m(rows, cols);
  auto it = rowMajor.begin();
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      m(r, c) = *it++;
    }
  }
  return m;
}

Eigen::VectorXd vector(std::initializer_list<double> values) {
  Eigen::VectorXd v(static_cast<Eigen::Index>(values.size()));
  std::copy(values.begin(), values.end(), v.data());
  return v;
}

QpProblem problem(int n) {
  QpProblem qp;
  qp.R = Eigen::MatrixXd::Identity(n, n);
  qp.a = Eigen::VectorXd::Zero(n);
  qp.E.resize(n, 0);
  qp.e.resize(0);
  qp.C.resize(n, 0);
  qp.c.resize(0);
  return qp;
}

Eigen::MatrixXd gram(const QpProblem& qp) {
  const Eigen::MatrixXd R = qp.R.triangularView<Eigen::Upper>();
  return R.transpose() * R;
}

/// 1/2 |R x|^2 + a^T x: the objective with less rounding than x^T G x when G is ill
/// conditioned and x large.
double objectiveOf(const QpProblem& qp, const Eigen::VectorXd& x) {
  return 0.5 * (qp.R.triangularView<Eigen::Upper>() * x).squaredNorm() + qp.a.dot(x);
}

/// Largest constraint violation of x, each relative to |rhs| + |normal| |x| + 1.
double constraintViolation(const QpProblem& qp, const Eigen::VectorXd& x) {
  double worst = 0.0;
  for (Eigen::Index j = 0; j < qp.E.cols(); ++j) {
    const double scale = 1.0 + std::abs(qp.e(j)) + qp.E.col(j).norm() * x.norm();
    worst = std::max(worst, std::abs(qp.E.col(j).dot(x) - qp.e(j)) / scale);
  }
  for (Eigen::Index i = 0; i < qp.C.cols(); ++i) {
    const double scale = 1.0 + std::abs(qp.c(i)) + qp.C.col(i).norm() * x.norm();
    worst = std::max(worst, (qp.c(i) - qp.C.col(i).dot(x)) / scale);
  }
  return worst;
}

/// max |G x + a - N u| / (|G| |x| + |a| + 1) over the reported active set, with a penalty
/// for negative inequality multipliers.
double kktResidual(const QpProblem& qp, const QpResult& result) {
  const auto me = static_cast<int>(qp.E.cols());
  Eigen::VectorXd residual = gram(qp) * result.x + qp.a;
  double negative = 0.0;
  for (std::size_t j = 0; j < result.active.size(); ++j) {
    const int id = result.active[j];
    const double u = result.multipliers(static_cast<Eigen::Index>(j));
    residual -= u * (id < me ? Eigen::VectorXd(qp.E.col(id)) : Eigen::VectorXd(qp.C.col(id - me)));
    if (id >= me) {
      negative = std::max(negative, -u);
    }
  }
  const double scale = gram(qp).norm() * result.x.norm() + qp.a.norm() + 1.0;
  return std::max(residual.cwiseAbs().maxCoeff(), negative) / scale;
}

// ---- Independent reference: enumerate active sets. ----

struct Reference {
  bool feasible = false;
  double objective = std::numeric_limits<double>::infinity();
  Eigen::VectorXd x;
  double normalCondition = 1.0;  ///< of the unit normals of the optimal active set
};

/// For every subset S of the inequalities (with all equalities), solves the KKT system
///     [G  -N] [x]   [-a ]
///     [N^T 0] [u] = [b_N]
/// by full-pivoting LU, skips singular systems (dependent normals), and keeps the points that
/// are primal feasible with inequality multipliers >= 0. A strictly convex QP has one such
/// point for generic data (a linearly independent optimal active set always exists); none means
/// the problem is infeasible.
Reference enumerateActiveSets(const QpProblem& qp) {
  constexpr double kReferenceTol = 1e-9;
  const auto n = static_cast<int>(qp.R.rows());
  const auto me = static_cast<int>(qp.E.cols());
  const auto mi = static_cast<int>(qp.C.cols());
  const Eigen::MatrixXd G = gram(qp);
  Reference best;
  for (unsigned mask = 0; mask < (1u << mi); ++mask) {
    const int q = me + __builtin_popcount(mask);
    if (q > n) {
      continue;
    }
    Eigen::MatrixXd N(n, q);
    Eigen::VectorXd rhs(q);
    int col = 0;
    // Normals scaled to unit length (multipliers keep their signs), so that the rank test
    // does not depend on how each constraint happens to be scaled.
    for (int j = 0; j < me; ++j, ++col) {
      const double norm = qp.E.col(j).norm();
      N.col(col) = qp.E.col(j) / norm;
      rhs(col) = qp.e(j) / norm;
    }
    for (int i = 0; i < mi; ++i) {
      if (mask & (1u << i)) {
        const double norm = qp.C.col(i).norm();
        N.col(col) = qp.C.col(i) / norm;
        rhs(col) = qp.c(i) / norm;
        ++col;
      }
    }
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n + q, n + q);
    K.topLeftCorner(n, n) = G;
    K.topRightCorner(n, q) = -N;
    K.bottomLeftCorner(q, n) = N.transpose();
    Eigen::VectorXd kktRhs(n + q);
    kktRhs << -qp.a, rhs;
    Eigen::FullPivLU<Eigen::MatrixXd> lu(K);
    lu.setThreshold(1e-13);
    if (lu.rank() < n + q) {
      continue;
    }
    Eigen::VectorXd solution = lu.solve(kktRhs);
    solution += lu.solve(kktRhs - K * solution);  // one step of iterative refinement
    const Eigen::VectorXd x = solution.head(n);
    const Eigen::VectorXd u = solution.tail(q);
    if (constraintViolation(qp, x) > kReferenceTol ||
        (q > me && u.tail(q - me).minCoeff() < -kReferenceTol * (1.0 + u.norm()))) {
      continue;
    }
    const double f = objectiveOf(qp, x);
    if (f < best.objective) {
      best.feasible = true;
      best.objective = f;
      best.x = x;
      if (q > 0) {
        const Eigen::JacobiSVD<Eigen::MatrixXd> svd(N);
        best.normalCondition = svd.singularValues()(0) / svd.singularValues()(q - 1);
      } else {
        best.normalCondition = 1.0;
      }
    }
  }
  return best;
}

// ---- Hand-checkable problems. ----

TEST(GoldfarbIdnani, UnconstrainedIdentity) {
  QpProblem qp = problem(2);
  qp.a = vector({-1.0, -2.0});
  const QpResult result = solveGoldfarbIdnani(qp);
  ASSERT_TRUE(result.feasible);
  EXPECT_NEAR(result.x(0), 1.0, 1e-15);
  EXPECT_NEAR(result.x(1), 2.0, 1e-15);
  EXPECT_NEAR(result.objective, -2.5, 1e-15);
  EXPECT_TRUE(result.active.empty());
}

TEST(GoldfarbIdnani, UnconstrainedGeneralFactor) {
  // G = R^T R = [4 2; 2 2]; G x = -a = (2, 0) gives x = (1, -1), f = -1.
  QpProblem qp = problem(2);
  qp.R = matrix(2, 2, {2.0, 1.0, 0.0, 1.0});
  qp.a = vector({-2.0, 0.0});
  const QpResult result = solveGoldfarbIdnani(qp);
  ASSERT_TRUE(result.feasible);
  EXPECT_NEAR(result.x(0), 1.0, 1e-14);
  EXPECT_NEAR(result.x(1), -1.0, 1e-14);
  EXPECT_NEAR(result.objective, -1.0, 1e-14);
}

TEST(GoldfarbIdnani, OneActiveBound) {
  // min 1/2 |x|^2 - (1, 2).x  s.t. -x2 >= -1 (active), x1 >= -5 (inactive):
  // x = (1, 1), f = -2, multiplier 1 (G x + a = (0, -1) = 1 * (0, -1)).
  QpProblem qp = problem(2);
  qp.a = vector({-1.0, -2.0});
  qp.C = matrix(2, 2, {0.0, 1.0, -1.0, 0.0});
  qp.c = vector({-1.0, -5.0});
  const QpResult result = solveGoldfarbIdnani(qp);
  ASSERT_TRUE(result.feasible);
  EXPECT_NEAR(result.x(0), 1.0, 1e-15);
  EXPECT_NEAR(result.x(1), 1.0, 1e-15);
  EXPECT_NEAR(result.objective, -2.0, 1e-15);
  ASSERT_EQ(result.active.size(), 1u);
  EXPECT_EQ(result.active[0], 0);
  EXPECT_NEAR(result.multipliers(0), 1.0, 1e-15);
  EXPECT_GE(result.iterations, 1);
}

TEST(GoldfarbIdnani, EqualityOnly) {
  // min 1/2 |x|^2  s.t. x1 + x2 = 1: x = (1/2, 1/2), f = 1/4, multiplier 1/2.
  QpProblem qp = problem(2);
  qp.E = matrix(2, 1, {1.0, 1.0});
  qp.e = vector({1.0});
  QpResult result = solveGoldfarbIdnani(qp);
  ASSERT_TRUE(result.feasible);
  EXPECT_NEAR(result.x(0), 0.5, 1e-15);
  EXPECT_NEAR(result.x(1), 0.5, 1e-15);
  EXPECT_NEAR(result.objective, 0.25, 1e-15);
  ASSERT_EQ(result.active.size(), 1u);
  EXPECT_NEAR(result.multipliers(0), 0.5, 1e-15);

  // The other side (the solver orients the equality internally): x1 + x2 = -1 gives a
  // multiplier of -1/2 for the equality as written.
  qp.e = vector({-1.0});
  result = solveGoldfarbIdnani(qp);
  ASSERT_TRUE(result.feasible);
  EXPECT_NEAR(result.x(0), -0.5, 1e-15);
  EXPECT_NEAR(result.multipliers(0), -0.5, 1e-15);
}

TEST(GoldfarbIdnani, RedundantEqualitiesAreSkipped) {
  // x1 + x2 = 1 three times (once scaled by 2): same answer, one equality active.
  QpProblem qp = problem(2);
  qp.E = matrix(2, 3, {1.0, 1.0, 2.0, 1.0, 1.0, 2.0});
  qp.e = vector({1.0, 1.0, 2.0});
  const QpResult result = solveGoldfarbIdnani(qp);
  ASSERT_TRUE(result.feasible);
  EXPECT_NEAR(result.x(0), 0.5, 1e-15);
  EXPECT_NEAR(result.x(1), 0.5, 1e-15);
  EXPECT_EQ(result.active.size(), 1u);
}

TEST(GoldfarbIdnani, Infeasible) {
  {  // x1 >= 1 and -x1 >= 0
    QpProblem qp = problem(2);
    qp.C = matrix(2, 2, {1.0, -1.0, 0.0, 0.0});
    qp.c = vector({1.0, 0.0});
    EXPECT_FALSE(solveGoldfarbIdnani(qp).feasible);
  }
  {  // x1 = 0 and x1 = 1
    QpProblem qp = problem(2);
    qp.E = matrix(2, 2, {1.0, 1.0, 0.0, 0.0});
    qp.e = vector({0.0, 1.0});
    EXPECT_FALSE(solveGoldfarbIdnani(qp).feasible);
  }
  {  // x1 + x2 = 1, x1 >= 1, x2 >= 1
    QpProblem qp = problem(2);
    qp.E = matrix(2, 1, {1.0, 1.0});
    qp.e = vector({1.0});
    qp.C = matrix(2, 2, {1.0, 0.0, 0.0, 1.0});
    qp.c = vector({1.0, 1.0});
    EXPECT_FALSE(solveGoldfarbIdnani(qp).feasible);
  }
  {  // a zero normal with a positive bound: 0 >= 1
    QpProblem qp = problem(2);
    qp.C = Eigen::MatrixXd::Zero(2, 1);
    qp.c = vector({1.0});
    EXPECT_FALSE(solveGoldfarbIdnani(qp).feasible);
  }
}

TEST(GoldfarbIdnani, DependentSimplexBounds) {
  // The blend-weight constraints in w directly (k = 2): w1 + w2 = 1, 0 <= w <= 1, with the
  // unconstrained minimum at (3, -2). The answer (1, 0) makes w1 <= 1 and w2 >= 0 tight, which
  // are dependent given the equality. f = 1/2 |w|^2 - (3, -2).w = 1/2 - 3.
  QpProblem qp = problem(2);
  qp.a = vector({-3.0, 2.0});
  qp.E = matrix(2, 1, {1.0, 1.0});
  qp.e = vector({1.0});
  qp.C = matrix(2, 4, {1.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, -1.0});
  qp.c = vector({0.0, 0.0, -1.0, -1.0});
  const QpResult result = solveGoldfarbIdnani(qp);
  ASSERT_TRUE(result.feasible);
  EXPECT_NEAR(result.x(0), 1.0, 1e-15);
  EXPECT_NEAR(result.x(1), 0.0, 1e-15);
  EXPECT_NEAR(result.objective, -2.5, 1e-14);
  EXPECT_LE(kktResidual(qp, result), 1e-14);
  // Only an independent subset is active: the equality and one of the two tight bounds.
  EXPECT_EQ(result.active.size(), 2u);
}

TEST(GoldfarbIdnani, DuplicatedConstraints) {
  // -x2 >= -1 four times (twice scaled): still x = (1, 1).
  QpProblem qp = problem(2);
  qp.a = vector({-1.0, -2.0});
  qp.C = matrix(2, 4, {0.0, 0.0, 0.0, 0.0, -1.0, -1.0, -2.0, -0.5});
  qp.c = vector({-1.0, -1.0, -2.0, -0.5});
  const QpResult result = solveGoldfarbIdnani(qp);
  ASSERT_TRUE(result.feasible);
  EXPECT_NEAR(result.x(0), 1.0, 1e-15);
  EXPECT_NEAR(result.x(1), 1.0, 1e-15);
  EXPECT_EQ(result.active.size(), 1u);
  EXPECT_LE(kktResidual(qp, result), 1e-15);
}

TEST(GoldfarbIdnani, NoVariables) {
  QpProblem qp = problem(0);
  QpResult result = solveGoldfarbIdnani(qp);
  EXPECT_TRUE(result.feasible);
  EXPECT_EQ(result.x.size(), 0);
  EXPECT_EQ(result.objective, 0.0);

  qp.E.resize(0, 1);
  qp.e = vector({0.0});
  qp.C.resize(0, 1);
  qp.c = vector({-1.0});
  EXPECT_TRUE(solveGoldfarbIdnani(qp).feasible);  // 0 = 0, 0 >= -1
  qp.c = vector({1.0});
  EXPECT_FALSE(solveGoldfarbIdnani(qp).feasible);  // 0 >= 1
  qp.c = vector({-1.0});
  qp.e = vector({1.0});
  EXPECT_FALSE(solveGoldfarbIdnani(qp).feasible);  // 0 = 1
}

void expectError(const QpProblem& qp, ErrorCode code, const char* what) {
  try {
    solveGoldfarbIdnani(qp);
    ADD_FAILURE() << what << ": no exception";
  } catch (const Error& error) {
    EXPECT_EQ(static_cast<int>(error.code()), static_cast<int>(code))
        << what << ": " << error.what();
  }
}

TEST(GoldfarbIdnani, BadInputThrows) {
  QpProblem qp = problem(2);
  qp.a = vector({1.0});
  expectError(qp, ErrorCode::kInternal, "a of the wrong size");
  qp = problem(2);
  qp.a(1) = std::numeric_limits<double>::quiet_NaN();
  expectError(qp, ErrorCode::kNumerical, "NaN in a");
  qp = problem(2);
  qp.R(1, 1) = 0.0;
  expectError(qp, ErrorCode::kNumerical, "singular R");
  qp = problem(2);
  qp.C = Eigen::MatrixXd::Ones(2, 1);
  qp.c = vector({std::numeric_limits<double>::infinity()});
  expectError(qp, ErrorCode::kNumerical, "infinite bound");
}

// ---- Random problems against the enumeration. ----

struct RandomQp {
  QpProblem qp;
  std::string kind;
  bool feasibleByConstruction = false;  ///< all constraints hold at a known point
};

/// A random strictly convex QP with n <= 6, up to 2 equalities and up to 8 inequalities.
/// Kinds: "feasible" (constraints built around a random point, some tight there),
/// "random" (random bounds, often infeasible), "dependent" (copies, multiples and mirrored
/// copies of constraints, some mirrors shifted so that the pair is infeasible), "ill" (R with a
/// condition number up to 1e4, G up to 1e8).
RandomQp randomQp(std::mt19937& rng, int variant) {
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const int n = std::uniform_int_distribution<int>(1, 6)(rng);
  const int me = std::uniform_int_distribution<int>(0, std::min(2, n))(rng);
  const int mi = std::uniform_int_distribution<int>(0, 8)(rng);
  RandomQp out;
  out.kind = variant == 0   ? "feasible"
             : variant == 1 ? "random"
             : variant == 2 ? "dependent"
                            : "ill";
  QpProblem& qp = out.qp;
  if (variant == 3) {
    // R of U diag(s) V^T with singular values s log-uniform in [1e-4, 1].
    const Eigen::MatrixXd U =
        Eigen::HouseholderQR<Eigen::MatrixXd>(Eigen::MatrixXd::NullaryExpr(n, n, [&] {
          return normal(rng);
        })).householderQ();
    const Eigen::MatrixXd V =
        Eigen::HouseholderQR<Eigen::MatrixXd>(Eigen::MatrixXd::NullaryExpr(n, n, [&] {
          return normal(rng);
        })).householderQ();
    const Eigen::VectorXd s =
        Eigen::VectorXd::NullaryExpr(n, [&] { return std::pow(10.0, -4.0 * uniform(rng)); });
    const Eigen::MatrixXd F = U * s.asDiagonal() * V.transpose();
    qp.R = Eigen::HouseholderQR<Eigen::MatrixXd>(F).matrixQR().triangularView<Eigen::Upper>();
  } else {
    qp.R = Eigen::MatrixXd::Zero(n, n);
    for (int i = 0; i < n; ++i) {
      qp.R(i, i) = (uniform(rng) < 0.5 ? -1.0 : 1.0) * (0.5 + 1.5 * uniform(rng));
      for (int j = i + 1; j < n; ++j) {
        qp.R(i, j) = 0.5 * normal(rng);
      }
    }
  }
  qp.a = 3.0 * Eigen::VectorXd::NullaryExpr(n, [&] { return normal(rng); });
  qp.E = Eigen::MatrixXd::NullaryExpr(n, me, [&] { return normal(rng); });
  qp.C = Eigen::MatrixXd::NullaryExpr(n, mi, [&] { return normal(rng); });
  const Eigen::VectorXd x0 = Eigen::VectorXd::NullaryExpr(n, [&] { return normal(rng); });
  out.feasibleByConstruction = variant == 0 || variant == 3;
  qp.e = qp.E.transpose() * x0;
  qp.c = qp.C.transpose() * x0;
  for (int i = 0; i < mi; ++i) {
    if (variant == 1) {
      qp.c(i) = 2.0 * normal(rng);
    } else if (uniform(rng) < 0.7) {
      qp.c(i) -= uniform(rng);  // else tight at x0
    }
  }
  if (variant == 2 && mi >= 2) {
    // Replace some inequalities by copies, positive multiples or mirrors (-n, -c: together
    // with the original they pin n.x = c) of others.
    for (int i = 1; i < mi; ++i) {
      if (uniform(rng) < 0.5) {
        const int source = std::uniform_int_distribution<int>(0, i - 1)(rng);
        const double choice = uniform(rng);
        const double scale = choice < 0.4 ? 1.0 : choice < 0.7 ? 0.5 + 2.0 * uniform(rng) : -1.0;
        qp.C.col(i) = scale * qp.C.col(source);
        qp.c(i) = scale * qp.c(source);
        if (choice > 0.85) {
          qp.c(i) += 0.5 * uniform(rng);  // a mirror past the original: infeasible
        }
      }
    }
  }
  return out;
}

TEST(GoldfarbIdnani, RandomProblemsMatchEnumeration) {
  const std::uint32_t seed = testSeed();
  std::mt19937 rng(seed);
  constexpr int kProblems = 4000;
  constexpr double kMaxNormalCondition = 1e3;
  int feasibleCount = 0;
  int infeasibleCount = 0;
  double worstObjective = 0.0;
  double worstConstraint = 0.0;
  double worstKkt = 0.0;
  int illPosed = 0;
  for (int index = 0; index < kProblems; ++index) {
    RandomQp random = randomQp(rng, index % 4);
    Reference reference = enumerateActiveSets(random.qp);
    // Keep well-posed problems: where the optimal active normals are nearly dependent (not
    // exactly, as in the "dependent" kind), the optimum moves by cond / eps times the rounding
    // of any solver, the reference's too, so no 1e-9 comparison is meaningful. The reference
    // also misses feasible points of such problems (its KKT systems are near singular).
    while ((reference.feasible && reference.normalCondition > kMaxNormalCondition) ||
           (!reference.feasible && random.feasibleByConstruction)) {
      ++illPosed;
      random = randomQp(rng, index % 4);
      reference = enumerateActiveSets(random.qp);
    }
    const QpProblem& qp = random.qp;
    const QpResult result = solveGoldfarbIdnani(qp);
    const std::string where =
        "problem " + std::to_string(index) + " (" + random.kind +
        ", n = " + std::to_string(qp.R.rows()) + ", me = " + std::to_string(qp.E.cols()) +
        ", mi = " + std::to_string(qp.C.cols()) + ", seed " + std::to_string(seed) + ")";
    ASSERT_EQ(result.feasible, reference.feasible) << where;
    if (!reference.feasible) {
      ++infeasibleCount;
      continue;
    }
    ++feasibleCount;
    const double scale = std::max(1.0, std::abs(reference.objective));
    const double objectiveError = std::abs(result.objective - reference.objective) / scale;
    const double recomputedError = std::abs(objectiveOf(qp, result.x) - result.objective) / scale;
    const double violation = constraintViolation(qp, result.x);
    const double kkt = kktResidual(qp, result);
    worstObjective = std::max({worstObjective, objectiveError, recomputedError});
    worstConstraint = std::max(worstConstraint, violation);
    worstKkt = std::max(worstKkt, kkt);
    ASSERT_LE(objectiveError, kQpObjectiveRelTol)
        << where << ": objective " << result.objective << ", reference " << reference.objective
        << ", violation " << violation << ", KKT " << kkt << ", reference violation "
        << constraintViolation(qp, reference.x);
    ASSERT_LE(recomputedError, kQpObjectiveRelTol) << where;
    ASSERT_LE(violation, kQpConstraintTol) << where;
    ASSERT_LE(kkt, kQpObjectiveRelTol) << where;
  }
  std::printf(
      "[ measured ] %d feasible, %d infeasible problems (%d ill-posed ones replaced); worst "
      "relative objective error %.3g "
      "(tolerance %.3g), worst relative constraint violation %.3g (tolerance %.3g), worst "
      "relative KKT residual %.3g (tolerance %.3g)\n",
      feasibleCount, infeasibleCount, illPosed, worstObjective, kQpObjectiveRelTol, worstConstraint,
      kQpConstraintTol, worstKkt, kQpObjectiveRelTol);
  EXPECT_GT(feasibleCount, kProblems / 2);
  EXPECT_GT(infeasibleCount, kProblems / 20);
  EXPECT_LT(illPosed, kProblems / 20);
}

}  // namespace
}  // namespace drivenshape
