// SPDX-License-Identifier: Apache-2.0
// The Evaluator: configures the registered stages once (their executor checks how they are
// wired), then has the executor run them in order on every block of frames.

#include <drivenshape/evaluator.h>

#include <cmath>

#include <drivenshape/error.h>
#include <drivenshape/version.h>

#include "executor.h"
#include "finite.h"
#include "json_text.h"
#include "settings_rows.h"
#include "stage.h"

namespace drivenshape {

namespace pipeline {

#define DS_STAGE(Name) std::unique_ptr<Stage> make##Name##Stage(Model& model);
#include "stage_list.h"
#undef DS_STAGE

const std::vector<StageFactory>& stageFactories() {
  static const std::vector<StageFactory> factories = {
#define DS_STAGE(Name) &make##Name##Stage,
#include "stage_list.h"
#undef DS_STAGE
  };
  return factories;
}

}  // namespace pipeline

WeightMode resolvedWeightMode(const EvaluatorSettings& settings, const Database& database) {
  if (settings.weightMode != WeightMode::kAuto) {
    return settings.weightMode;
  }
  // The model runs in the local blend with the correction, on every triangle, with one set of
  // weights per frame; settings that ask for something else are the QP's.
  const bool modelFits = settings.correct && settings.blend == BlendMode::kLocal &&
                         !settings.bindingMask && !settings.regions &&
                         settings.maxWeightChange <= 0;
  return !database.poseModel.empty() && modelFits ? WeightMode::kModel : WeightMode::kQp;
}

bool blendsLocally(const EvaluatorSettings& settings) {
  return settings.blend == BlendMode::kLocal && settings.correct &&
         settings.weightMode != WeightMode::kBind;
}

namespace {

/// The evaluator's output check: a non-finite position is an error naming the frame and the
/// vertex, never a silent output (blocks computed on the device skip the backends' checks).
///   cloth count x 3Vd, frames count
void checkCloth(const pipeline::Model& model, int count, const int* frames, const float* cloth) {
  const std::size_t dd = model.drivenValues;
  for (int i = 0; i < count; ++i) {
    const float* frame = cloth + static_cast<std::size_t>(i) * dd;
    const std::size_t bad = firstNonFinite(frame, dd);
    if (bad < dd) {
      DS_THROW(kNumerical, "frame ", frames[i], ": cloth vertex ", bad / 3,
               " came out of the pipeline as ", std::isnan(frame[bad]) ? "NaN" : "infinity",
               "; the database or the settings give non-finite positions for this pose");
    }
  }
}

}  // namespace

struct Evaluator::Impl {
  Impl(const Database& database, EvaluatorSettings settings, Device& device)
      : model(database, std::move(settings), device), executor(model) {}

  /// The settings hash in the layout the bake's EXR headers have had since version 0.1 (a
  /// file-format contract: a resume compares it): the settings table's rows in their order
  /// (pipeline::hashSettings), then what stages added since append (Stage::addToHash).
  std::uint64_t settingsHash(const OutputHashFields* output, const char* version) const {
    // Of the built-in stages, the resolution appends its side table, only when some driven
    // vertex lives inside (never for cloth).
    Hasher tail(pipeline::hashSettings(model, output, version));
    executor.addToHash(tail);
    return tail.value();
  }

  pipeline::Model model;
  pipeline::Executor executor;  ///< the stages and their batch (reused: it keeps its buffers)
};

Evaluator::Evaluator(const Database& database, EvaluatorSettings settings, Device& device)
    : mImpl(std::make_unique<Impl>(database, std::move(settings), device)) {}

Evaluator::~Evaluator() = default;

Evaluation Evaluator::evaluate(const std::vector<int>& frames, const std::vector<float>& driver) {
  const std::size_t expected = frames.size() * mImpl->model.driverValues;
  if (driver.size() != expected) {
    DS_THROW(kUsage, "evaluate: ", frames.size(), " frames of a driver with ", mImpl->model.vp,
             " vertices need ", expected, " floats, got ", driver.size());
  }
  Evaluation out;
  out.cloth.resize(frames.size() * mImpl->model.drivenValues);
  out.records.resize(frames.size());
  out.seconds = evaluate(static_cast<int>(frames.size()), frames.data(), driver.data(),
                         out.cloth.data(), out.records.data());
  return out;
}

StageSeconds Evaluator::evaluate(int frameCount, const int* frames, const float* driver,
                                 float* cloth, FrameRecord* records, int warmup) {
  pipeline::Model& model = mImpl->model;
  if (frameCount < 0 || warmup < 0 || (frameCount > 0 && warmup >= frameCount)) {
    DS_THROW(kUsage, "evaluate: ", frameCount, " frames with a warm-up of ", warmup,
             "; the warm-up must leave at least one frame");
  }
  StageSeconds seconds;
  if (frameCount == 0) {
    return seconds;
  }
  for (int i = 0; i < frameCount; ++i) {
    const float* xyz = driver + static_cast<std::size_t>(i) * model.driverValues;
    const std::size_t bad = firstNonFinite(xyz, model.driverValues);
    if (bad < model.driverValues) {
      DS_THROW(kInput, "driver frame ", frames[i], " vertex ", bad / 3,
               " is not a finite number; fix the driver or leave the frame out");
    }
  }
  pipeline::BatchInput input;
  input.solveCount = frameCount;
  input.warm = warmup;
  input.frames = frames;
  input.driver = driver;
  input.cloth = cloth;
  input.records = records;
  input.driverValues = model.driverValues;
  input.drivenValues = model.drivenValues;
  const float* result = mImpl->executor.run(input, seconds);
  checkCloth(model, frameCount - warmup, frames + warmup, result);
  return seconds;
}

int Evaluator::historyFrames() const {
  const pipeline::Model& model = mImpl->model;
  return model.settings.weightMode == WeightMode::kModel ? model.db.poseModel.historyNeeded() : 0;
}

double Evaluator::coverageTolerance() const {
  return pipeline::coverageTolerance(mImpl->model);
}

void Evaluator::checkFrames(const std::vector<int>& frames) const {
  if (mImpl->model.layerStack) {
    mImpl->model.layerStack->checkFrames(frames);
  }
}

void Evaluator::resetTemporalBound() {
  mImpl->executor.reset(false);
}

void Evaluator::resetHistory() {
  mImpl->executor.reset(true);
}

std::uint64_t Evaluator::settingsHash() const {
  return mImpl->settingsHash(nullptr, kVersion);
}

std::uint64_t Evaluator::settingsHash(const OutputHashFields& output) const {
  return mImpl->settingsHash(&output, kVersion);
}

std::uint64_t Evaluator::settingsHashOfVersion(const std::string& version,
                                               const OutputHashFields* output) const {
  return mImpl->settingsHash(output, version.c_str());
}

std::string Evaluator::describeSettings() const {
  nlohmann::json json = nlohmann::json::object();
  pipeline::describeSettings(mImpl->model, json);
  json["stages"] = stageNames();
  mImpl->executor.describe(json);
  return jsonText(json);
}

const std::vector<std::string>& Evaluator::warnings() const {
  return mImpl->model.warnings;
}

std::string Evaluator::describeLayers() const {
  return mImpl->model.layerStack ? mImpl->model.layerStack->describe() : std::string("{}");
}

std::vector<std::string> Evaluator::stageNames() const {
  std::vector<std::string> names;
  for (const auto& stage : mImpl->executor.stages()) {
    names.emplace_back(stage->name());
  }
  return names;
}

const Database& Evaluator::database() const {
  return mImpl->model.db;
}

const EvaluatorSettings& Evaluator::settings() const {
  return mImpl->model.settings;
}

std::string Evaluator::deviceName() const {
  return mImpl->model.device.description();
}

int Evaluator::driverVertexCount() const {
  return mImpl->model.vp;
}

int Evaluator::drivenVertexCount() const {
  return mImpl->model.vd;
}

std::size_t Evaluator::bytesPerFrame() const {
  // Driver frames (read, aligned, blended) and the pipeline's cloth blocks (blend, two output
  // blocks) in float, plus two hit arrays.
  const std::size_t vp = mImpl->model.vp, vd = mImpl->model.vd;
  return sizeof(float) * 3 * (3 * vp + 3 * vd) + 2 * sizeof(SurfaceHit) * vd;
}

}  // namespace drivenshape
