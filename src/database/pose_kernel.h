// SPDX-License-Identifier: Apache-2.0
#pragma once

// The pose model's kernel, shared by its fit (pose_model.cpp) and the frame suggestion
// (frame_suggestion.cpp).

#include <Eigen/Core>

namespace drivenshape {

/// k(x, y) = linearWeight x.y + exp(-|x - y|^2 / (2 lengthScale^2)) between the rows of `a`
/// and those of `b`: rows(a) x rows(b).
Eigen::MatrixXd poseKernel(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double lengthScale,
                           double linearWeight);

}  // namespace drivenshape
