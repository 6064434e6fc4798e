// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <string>
#include <vector>

namespace drivenshape::cli {

/// `drivenshape eval`: a bake against the truth it replaces (error, frame-to-frame jumps), with
/// a driver the penetrations of the bake and of the truth, and with --baseline the binding
/// baseline for the same frames, side by side, and with --report the bake report's coverage
/// verdict against the truth. Parses its words, calls the library (evaluateShot,
/// checkCoverage) and returns the exit code; errors propagate as drivenshape::Error to main's
/// single catch.
int runEval(const std::vector<std::string>& args);

}  // namespace drivenshape::cli
