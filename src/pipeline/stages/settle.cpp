// SPDX-License-Identifier: Apache-2.0
// Settle (docs/method.md, "Strain limit"): with the strain limit and the resolution on, the cloth
// vertices the resolution left shallowly inside the body come out just in front of the skin. In
// a crease (the inside of a bent elbow, where the forearm's skin meets the upper arm's) the
// resolution moves a vertex out of one side along its closest point's normal and into the
// other; the limit, which brings the compressed cloth there back to its length, leaves more
// vertices in the crease than the bake without it. Each cloth vertex now inside the body by at
// most kSettleDepth skin offsets (fading to none at 1.5 times that), or closer to the skin than
// kSettleOffset of an offset, moves onto the plane at kSettleOffset in front of its closest point
// (ClosestBackend::skinPlanes, then StrainLimitBackend::keepInFront). Deeper vertices are the
// resolution's exit fade's to hold: moved again, a vertex deep in the trousers' crotch jumps
// when its nearest exit changes side. The audit after counts what is left.

#include <memory>

#include "../stage.h"
#include "strain_limit.h"

namespace drivenshape::pipeline {
namespace {

/// Where a settled vertex goes, in skin offsets in front of its closest point: clear of the
/// skin, well within the offset the resolution keeps, so that a vertex between two sides of a
/// crease narrower than two offsets stays out of both. Chosen on the validation clips
/// (docs/validation.md, "Strain").
constexpr double kSettleOffset = 0.1;

/// How deep inside the body, in skin offsets, a vertex is still settled all the way; deeper, its
/// plane sinks away until there is none at 1.5 times this (ClosestBackend::skinPlanes). 1 offset
/// (2 mm at the default): the crease vertices the resolution leaves are within 1.6 mm on the
/// sleeve's extremes clip; with 0.5 offsets 0.28 per frame stayed in there, none with 1.
constexpr double kSettleDepth = 1.0;

class SettleStage final : public Stage {
 public:
  explicit SettleStage(Model& model) : mModel(model) {
    declare(Arrays{Array::Shot, Array::Cloth, Array::AuditHits, Array::AuditAnswered},
            kAuditArrays | Arrays{Array::SkinPlanes, Array::Cloth});
    mBackend = model.device.makeStrainLimit(model.threads);
  }

  const char* name() const override { return "settle"; }

  void run(Batch& batch) override {
    const int count = batch.count();
    const float offset = static_cast<float>(mModel.settings.skinOffset);
    const float settled = static_cast<float>(kSettleOffset * offset);
    DeviceArray& shot = batch.in<Array::Shot>();
    DeviceArray& cloth = batch.out<Array::Cloth>();
    // The resolution's answers hold here: it left every vertex they answered where it was, and
    // they proved it the skin offset clear, more than this.
    findSkinPlanes(mModel, batch, shot, cloth, settled, settled,
                   static_cast<float>(kSettleDepth * offset), /*keep=*/true);
    mBackend->keepInFrontBlock(count, mModel.vd, cloth, batch.out<Array::SkinPlanes>());
  }

 private:
  Model& mModel;
  std::unique_ptr<StrainLimitBackend> mBackend;
};

}  // namespace

std::unique_ptr<Stage> makeSettleStage(Model& model) {
  if (!limitsWithSkinPlanes(model)) {
    return nullptr;
  }
  return std::make_unique<SettleStage>(model);
}

}  // namespace drivenshape::pipeline
