// SPDX-License-Identifier: Apache-2.0
#pragma once
// The dual active-set solver behind solveGoldfarbIdnani, taking views so that callers that
// solve many problems with the same matrices (SimplexLeastSquares, one problem per frame) do
// not copy them into a QpProblem each time.

#include "qp.h"

#include <Eigen/Core>

namespace drivenshape::detail {

/// Same problem and result as solveGoldfarbIdnani (see drivenshape/qp.h):
///
///     minimise 1/2 x^T R^T R x + a^T x   s.t.  E^T x = e,  C^T x >= c
///
///   R  n by n, upper triangular (entries below the diagonal are ignored), nonsingular
///   a  n;  E  n by me (or 0 by 0 when me = 0);  e  me;  C  n by mi (or 0 by 0);  c  mi
///
/// Throws Error(kInternal) on inconsistent sizes, Error(kNumerical) on non-finite input, a
/// singular R, or when the iteration cap 10 (n + me + mi) + 50 is reached.
QpResult solveGoldfarbIdnani(const Eigen::Ref<const Eigen::MatrixXd>& R,
                             const Eigen::Ref<const Eigen::VectorXd>& a,
                             const Eigen::Ref<const Eigen::MatrixXd>& E,
                             const Eigen::Ref<const Eigen::VectorXd>& e,
                             const Eigen::Ref<const Eigen::MatrixXd>& C,
                             const Eigen::Ref<const Eigen::VectorXd>& c);

}  // namespace drivenshape::detail
