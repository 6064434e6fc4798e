// SPDX-License-Identifier: Apache-2.0
// Penetration resolution on the shot's driver (every triangle): every driven vertex stays on
// its side of the skin (Model::sides), at least the skin offset from it. Cloth inside the body
// or closer than the offset moves out to the offset from its closest point, the nearest way
// (EvaluatorSettings::resolveDirection); a vertex that lives under the skin (a muscle) and came
// closer than the offset, or through the skin, moves in to the offset; a vertex deep on the wrong
// side with two nearly equally near exits moves only part of the way (EvaluatorSettings::exitFade).
// With the audit on, the vertices on the wrong side before the move are counted here too.

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class ResolveStage final : public Stage {
 public:
  explicit ResolveStage(Model& model) : mModel(model), mKeep(limitsWithSkinPlanes(model)) {
    // After a limit with skin planes, the certificate's answers of the points that moved little
    // in it are kept (StrainLimitStage): only the others are checked and searched again.
    declare(Arrays{Array::Shot, Array::Cloth}
                .with(Array::AuditHits, mKeep)
                .with(Array::AuditAnswered, mKeep),
            kAuditArrays | Arrays{Array::Cloth, Array::Moved});
    model.sides();
    model.unmaskedClosest().setExitFade(static_cast<float>(model.settings.exitFade));
    model.unmaskedClosest().setAlongNormal(model.settings.resolveDirection ==
                                           ResolveDirection::kNormal);
  }

  const char* name() const override { return "resolve"; }

  /// The side table changes the result only where some vertex lives inside; cloth databases
  /// keep the hash they always had.
  void addToHash(Hasher& hasher) const override {
    if (mModel.insideVertices() > 0) {
      hasher.add(mModel.sides().data(), mModel.sides().size());
    }
  }

  void describe(nlohmann::json& settings) const override { describeSides(mModel, settings); }

  void run(Batch& batch) override {
    // The hits serve the resolution with this offset and the inside count only, so points
    // proven at least the offset clear of the driver need no search.
    const float offset = static_cast<float>(mModel.settings.skinOffset);
    DeviceArray& shot = batch.in<Array::Shot>();
    DeviceArray& cloth = batch.out<Array::Cloth>();
    if (mModel.settings.audit) {
      countInside(mModel, batch, shot, cloth, &FrameRecord::insideCorrected, offset, mKeep);
    } else {
      auditClosest(mModel, batch, shot, cloth, offset, mKeep);
    }
    std::vector<int>& moved = batch.out<Array::Moved>();
    moved.assign(batch.count(), 0);
    mModel.unmaskedClosest().resolveBlock(batch.count(), shot, batch.out<Array::AuditHits>(),
                                          offset, cloth, moved.data());
    FrameRecord* records = batch.out<Array::Records>();
    for (int i = 0; i < batch.count(); ++i) {
      records[i].resolved = moved[i];
    }
  }

 private:
  Model& mModel;
  bool mKeep = false;  ///< keep the strain limit's certificate answers
};

}  // namespace

std::unique_ptr<Stage> makeResolveStage(Model& model) {
  if (!model.settings.resolve) {
    return nullptr;
  }
  return std::make_unique<ResolveStage>(model);
}

}  // namespace drivenshape::pipeline
