// SPDX-License-Identifier: Apache-2.0
// The executor: the stages' wiring checked once, then each stage run on the batch with only the
// arrays it declared open to it, timed by its name.

#include "executor.h"

#include <chrono>
#include <stdexcept>

#include "stopwatch.h"

namespace drivenshape::pipeline {

void checkWiring(const std::vector<std::unique_ptr<Stage>>& stages) {
  Arrays written = kInputArrays;
  for (const auto& stage : stages) {
    for (const Array array : stage->reads().list()) {
      if (!written.has(array)) {
        throw std::logic_error(std::string("stage '") + stage->name() + "' reads '" +
                               arrayName(array) +
                               "', which is not an input and no earlier stage writes");
      }
    }
    written = written | stage->writes();
  }
  if (!written.has(Array::Cloth)) {
    throw std::logic_error(std::string("no stage writes '") + arrayName(Array::Cloth) + "'");
  }
}

Executor::Executor(Model& model) : mBatch(model.device) {
  for (StageFactory factory : stageFactories()) {
    if (std::unique_ptr<Stage> stage = factory(model)) {
      mStages.push_back(std::move(stage));
    }
  }
  checkWiring(mStages);
}

Executor::Executor(Device& device, std::vector<std::unique_ptr<Stage>> stages)
    : mBatch(device), mStages(std::move(stages)) {
  checkWiring(mStages);
}

void Batch::open(const Stage* stage) {
  mStage = stage != nullptr ? stage->name() : nullptr;
  mReadable = stage != nullptr ? stage->reads() | stage->writes() : Arrays();
  mWritable = stage != nullptr ? stage->writes() : Arrays();
}

std::vector<StagePlan> Executor::plan() const {
  std::vector<StagePlan> plan;
  for (const auto& stage : mStages) {
    plan.push_back({stage->name(), stage->reads(), stage->writes()});
  }
  return plan;
}

const float* Executor::run(const BatchInput& input, StageSeconds& seconds) {
  Batch& batch = mBatch;
  batch.mSolveCount = input.solveCount;
  batch.mWarm = input.warm;
  batch.mCount = input.solveCount - input.warm;
  batch.mFrames = input.frames;
  batch.mDriver = input.driver;
  batch.mAligned = input.driver;
  batch.mRecords = input.records;
  batch.mLayersApplied = false;
  const std::size_t dv = input.driverValues;
  batch.mDriverFrames.view(input.driver, static_cast<std::size_t>(input.solveCount) * dv);
  batch.mShotFrames.view(input.driver + static_cast<std::size_t>(input.warm) * dv,
                         static_cast<std::size_t>(batch.mCount) * dv);
  batch.mCloth.view(input.cloth, static_cast<std::size_t>(batch.mCount) * input.drivenValues);
  for (int i = 0; i < batch.mCount; ++i) {
    input.records[i].frame = input.frames[input.warm + i];
  }
  for (const auto& stage : mStages) {
    batch.open(stage.get());
    const auto start = std::chrono::steady_clock::now();
    stage->run(batch);
    seconds[stage->name()] += secondsSince(start);
  }
  batch.open(nullptr);
  // The cloth comes back from the device here unless a stage (the audit) read it already.
  return batch.mCloth.read<float>();
}

void Executor::addToHash(Hasher& hasher) const {
  for (const auto& stage : mStages) {
    stage->addToHash(hasher);
  }
}

void Executor::describe(nlohmann::json& settings) const {
  for (const auto& stage : mStages) {
    stage->describe(settings);
  }
}

void Executor::reset(bool all) {
  for (const auto& stage : mStages) {
    stage->reset(all);
  }
}

}  // namespace drivenshape::pipeline
