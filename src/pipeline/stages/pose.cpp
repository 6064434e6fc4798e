// SPDX-License-Identifier: Apache-2.0
// The pose model's weights (drivenshape/pose_model.h): per frame, the pose features of the
// shot's driver (joint rotations of its rigid parts, their velocity and history), the basis
// weights of the learned correction, and the coverage figures (how new the pose is, the
// predicted error, whether the frame should be simulated). Velocity and history read the
// earlier frames of the block (the bake's warm-up frames, read from the driver cache before
// each batch, so chunked bakes equal whole ones), else those of the previous call when they
// continue it (live playback), else the earliest frame there is stands in.

#include <algorithm>
#include <deque>

#include "parallel.h"

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class PoseStage final : public Stage {
 public:
  explicit PoseStage(Model& model)
      : mModel(model), mPose(model.db.poseModel), mPredictor(mPose, model.db.driverMesh) {
    declare({Array::Frames, Array::Driver}, {Array::Weights, Array::Records});
  }

  const char* name() const override { return "weights"; }

  void describe(nlohmann::json& settings) const override {
    settings["pose_model"] = {{"parts", mPose.partCount()},
                              {"rank", mPose.rank()},
                              {"reference_frames", mPose.frameCount()},
                              {"velocity_lag", mPose.velocityLag},
                              {"history_frames", mPose.historyFrames},
                              {"cross_validation_error", mPose.crossValidationError},
                              {"binding_error", mPose.bindingError},
                              {"verdict_level", mPose.verdictLevel},
                              {"verdict_margin", mPose.verdictMargin}};
    if (mPose.siblingWeight > 0.0) {
      settings["pose_model"]["sibling_weight"] = mPose.siblingWeight;
    }
    if (mPose.clipMixtureWeight > 0.0) {
      settings["pose_model"]["per_clip_models"] = {{"clips", mPose.clipSizes.size()},
                                                   {"weight", mPose.clipMixtureWeight}};
    }
    settings["coverage_tolerance"] = coverageTolerance(mModel);
  }

  void reset(bool /*all*/) override { mHistory.clear(); }

  void run(Batch& batch) override {
    const int n = batch.solveCount(), pf = mPose.poseFeatureCount(), d = mPose.featureCount();
    // The remembered frames in front of the block, then the block's own.
    const int kept = static_cast<int>(mHistory.size());
    const int total = kept + n;
    mFrames.resize(static_cast<std::size_t>(total));
    mPoseFeatures.resize(static_cast<std::size_t>(total) * pf);
    for (int h = 0; h < kept; ++h) {
      mFrames[h] = mHistory[h].first;
      std::copy(mHistory[h].second.begin(), mHistory[h].second.end(), &mPoseFeatures[h * pf]);
    }
    std::copy_n(batch.in<Array::Frames>(), n, mFrames.begin() + kept);
    const float* driver = batch.in<Array::Driver>();
    parallelFor(n, mModel.threads, [&](int i) {
      mPredictor.poseFeatures(driver + i * mModel.driverValues,
                              &mPoseFeatures[static_cast<std::size_t>(kept + i) * pf]);
    });
    const int rank = mPose.rank();
    const double tolerance = coverageTolerance(mModel);
    std::vector<float>& weights = batch.out<Array::Weights>();
    weights.assign(static_cast<std::size_t>(batch.count()) * (rank + 1), 0.0f);
    FrameRecord* records = batch.out<Array::Records>();
    parallelFor(batch.count(), mModel.threads, [&](int i) {
      std::vector<double> x(static_cast<std::size_t>(d));
      mPredictor.features(mPoseFeatures.data(), mFrames.data(), total, kept + batch.warm() + i,
                          x.data());
      const PosePredictor::Prediction p = mPredictor.predict(x.data());
      float* w = &weights[static_cast<std::size_t>(i) * (rank + 1)];
      w[0] = 1.0f;
      for (int j = 0; j < rank; ++j) {
        w[1 + j] = static_cast<float>(p.weights[j]);
      }
      FrameRecord& record = records[i];
      record.weights.clear();
      record.atZero.clear();
      record.atOne.clear();
      record.poseDistance = p.sigma;
      record.predictedError = p.predictedError;
      record.errorBound = mPose.errorBound(p.sigma);
      record.flagged = record.errorBound > tolerance ? 1 : 0;
    });
    // Remember the block's last frames for a call that continues it.
    const int need = mPose.historyNeeded();
    for (int i = std::max(0, total - need); i < total; ++i) {
      mHistory.emplace_back(
          mFrames[i], std::vector<double>(&mPoseFeatures[i * pf], &mPoseFeatures[i * pf] + pf));
    }
    while (static_cast<int>(mHistory.size()) > need) {
      mHistory.pop_front();
    }
  }

 private:
  Model& mModel;
  const PoseModel& mPose;
  const PosePredictor mPredictor;
  std::deque<std::pair<int, std::vector<double>>> mHistory;  ///< frame, pose features
  std::vector<int> mFrames;
  std::vector<double> mPoseFeatures;
};

}  // namespace

std::unique_ptr<Stage> makePoseStage(Model& model) {
  if (model.settings.weightMode != WeightMode::kModel) {
    return nullptr;
  }
  return std::make_unique<PoseStage>(model);
}

}  // namespace drivenshape::pipeline
