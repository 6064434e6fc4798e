// SPDX-License-Identifier: Apache-2.0
#pragma once

// The executor of the evaluator's pipeline: it owns the stages (in stage_list.h's order) and the
// Batch they work on. Configured, it checks the wiring once: every array a stage reads
// (Stage::reads) is an input of the call (kInputArrays) or written by an earlier stage, and
// some stage writes the cloth. Per call, it sets the batch's inputs, then runs each stage with
// the batch open to what that stage declared, timing it by its name.

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stage.h"

namespace drivenshape::pipeline {

/// One stage's wiring: its name and what it reads and writes.
struct StagePlan {
  std::string name;
  Arrays reads, writes;
};

/// The caller's memory for one call: `solveCount` frames of the driver, of which the last
/// solveCount - warm go to the cloth and the records.
struct BatchInput {
  int solveCount = 0;
  int warm = 0;
  const int* frames = nullptr;     ///< solveCount frame numbers
  const float* driver = nullptr;   ///< solveCount x driverValues
  float* cloth = nullptr;          ///< (solveCount - warm) x drivenValues
  FrameRecord* records = nullptr;  ///< solveCount - warm
  std::size_t driverValues = 0, drivenValues = 0;
};

/// Throws std::logic_error naming the stage and the array when a stage reads an array that is
/// neither an input nor written by an earlier stage, or when no stage writes the cloth.
void checkWiring(const std::vector<std::unique_ptr<Stage>>& stages);

class Executor {
 public:
  /// The registered stages the model's settings keep (stageFactories), wiring checked.
  explicit Executor(Model& model);
  /// These stages on `device`, wiring checked.
  Executor(Device& device, std::vector<std::unique_ptr<Stage>> stages);

  const std::vector<std::unique_ptr<Stage>>& stages() const { return mStages; }
  /// Each stage's name and arrays, in order.
  std::vector<StagePlan> plan() const;

  /// Sets the batch's inputs from `input` (the records' frame numbers too), runs every stage,
  /// adding its seconds to `seconds[name]`, and returns the cloth on the host (downloaded unless
  /// a stage read it already): (solveCount - warm) x drivenValues, input.cloth.
  const float* run(const BatchInput& input, StageSeconds& seconds);

  /// Every stage's Stage::addToHash, Stage::describe, Stage::reset, in order.
  void addToHash(Hasher& hasher) const;
  void describe(nlohmann::json& settings) const;
  void reset(bool all);

 private:
  Batch mBatch;  ///< made before the stages (its arrays first on the device)
  std::vector<std::unique_ptr<Stage>> mStages;
};

}  // namespace drivenshape::pipeline
