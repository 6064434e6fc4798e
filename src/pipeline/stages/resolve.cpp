// Penetration resolution on the shot's driver (every triangle): cloth inside the body or closer
// than the skin offset moves out to the offset along the pseudo-normal at its closest point.
// With the audit on, the cloth inside before the move is counted here too.

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class ResolveStage final : public Stage {
 public:
  explicit ResolveStage(Model& model) : mModel(model) { model.audit(); }

  const char* name() const override { return "resolve"; }

  void run(Batch& batch) override {
    // The hits serve the resolution with this offset and the inside count only, so points
    // proven at least the offset clear of the driver need no search.
    const float offset = static_cast<float>(mModel.settings.skinOffset);
    if (mModel.settings.audit) {
      countInside(mModel, batch, batch.shot(), batch.cloth, &FrameRecord::insideCorrected, offset);
    } else {
      auditClosest(mModel, batch, batch.shot(), batch.cloth, offset);
    }
    batch.moved.assign(batch.count, 0);
    mModel.audit().resolveBlock(batch.count, batch.shot(), batch.auditHits, offset, batch.cloth,
                                batch.moved.data());
    for (int i = 0; i < batch.count; ++i) {
      batch.records[i].resolved = batch.moved[i];
    }
  }

 private:
  Model& mModel;
};

}  // namespace

std::unique_ptr<Stage> makeResolveStage(Model& model) {
  if (!model.settings.resolve) {
    return nullptr;
  }
  return std::make_unique<ResolveStage>(model);
}

}  // namespace drivenshape::pipeline
