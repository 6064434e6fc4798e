// SPDX-License-Identifier: Apache-2.0
// Audit of the world blend before any correction: how many cloth vertices the blend alone puts
// on the wrong side of the (aligned) shot driver's skin (inside, for cloth; Model::sides), the
// figure the correction exists to fix.

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class BlendAuditStage final : public Stage {
 public:
  explicit BlendAuditStage(Model& model) : mModel(model) {
    declare({Array::Aligned, Array::Driven}, kAuditArrays);
    model.sides();
  }

  const char* name() const override { return "audit"; }

  void run(Batch& batch) override {
    countInside(mModel, batch, batch.alignedShot(mModel.driverValues), batch.in<Array::Driven>(),
                &FrameRecord::insideBefore);
  }

 private:
  Model& mModel;
};

}  // namespace

std::unique_ptr<Stage> makeBlendAuditStage(Model& model) {
  if (!model.settings.audit || model.local) {
    return nullptr;
  }
  return std::make_unique<BlendAuditStage>(model);
}

}  // namespace drivenshape::pipeline
