// SPDX-License-Identifier: Apache-2.0
// The per-frame audit of the final cloth: vertices on the wrong side of the shot's driver's
// skin (Model::sides: inside for cloth; recounted only when the resolution moved something or
// layers changed the cloth), binding switches and the largest jump against the previous
// evaluated frame.

#include <algorithm>
#include <cmath>

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class AuditStage final : public Stage {
 public:
  explicit AuditStage(Model& model)
      : mModel(model),
        mSwitches(model.settings.correct && !model.local),
        mLayers(!model.settings.layers.empty()),
        mSettles(limitsWithSkinPlanes(model)) {
    // The resolution's hits are kept for the points it proved clear (countAfter).
    const bool resolve = model.settings.resolve;
    declare(Arrays{Array::Shot, Array::Cloth, Array::Records}
                .with(Array::Moved, resolve)
                .with(Array::AuditHits, resolve)
                .with(Array::AuditAnswered, resolve)
                .with(Array::LayersApplied, mLayers)
                .with(Array::Hits, mSwitches),
            kAuditArrays);
    model.sides();
  }

  const char* name() const override { return "audit"; }

  void describe(nlohmann::json& settings) const override { describeSides(mModel, settings); }

  void reset(bool all) override {
    if (all) {
      mPreviousOutput.clear();
      mPreviousHits.clear();
    }
  }

  void run(Batch& batch) override {
    countAfter(batch);
    const bool switches = mSwitches;
    const std::size_t dd = mModel.drivenValues;
    const int vd = mModel.vd;
    const int count = batch.count();
    // The cloth's one trip back from the device (into the caller's memory).
    const float* cloth = batch.in<Array::Cloth>().read<float>();
    const SurfaceHit* hits = switches ? batch.in<Array::Hits>().read<SurfaceHit>() : nullptr;
    FrameRecord* records = batch.out<Array::Records>();
    for (int i = 0; i < count; ++i) {
      FrameRecord& record = records[i];
      const float* now = cloth + i * dd;
      const float* before = i > 0                     ? cloth + (i - 1) * dd
                            : mPreviousOutput.empty() ? nullptr
                                                      : mPreviousOutput.data();
      if (before != nullptr) {
        record.maxJump = 0.0;
        for (int v = 0; v < vd; ++v) {
          const double dx = now[3 * v] - before[3 * v], dy = now[3 * v + 1] - before[3 * v + 1],
                       dz = now[3 * v + 2] - before[3 * v + 2];
          const double jump = std::sqrt(dx * dx + dy * dy + dz * dz);
          if (jump > record.maxJump) {
            record.maxJump = jump;
            record.maxJumpVertex = v;
          }
        }
      }
      if (switches) {
        const SurfaceHit* nowHits = &hits[static_cast<std::size_t>(i) * vd];
        const SurfaceHit* beforeHits = i > 0 ? &hits[static_cast<std::size_t>(i - 1) * vd]
                                       : mPreviousHits.empty() ? nullptr
                                                               : mPreviousHits.data();
        if (beforeHits != nullptr) {
          record.bindingSwitches = 0;
          for (int v = 0; v < vd; ++v) {
            record.bindingSwitches += nowHits[v].triangle != beforeHits[v].triangle ? 1 : 0;
          }
        }
      }
    }
    mPreviousOutput.assign(cloth + (count - 1) * dd, cloth + count * dd);
    if (switches) {
      const std::size_t last = static_cast<std::size_t>(count - 1) * vd;
      mPreviousHits.assign(hits + last, hits + last + vd);
    }
  }

 private:
  /// Wrong-side counts after the resolution, the settle stage and layers; reuses the resolution's
  /// count when nothing moved since, and, when only the resolution and the settle stage moved
  /// points, their answers for the points they proved clear (they left them where they were).
  /// The settle stage counts no moves: after it the cloth is always counted again.
  void countAfter(Batch& batch) {
    const bool resolve = mModel.settings.resolve;
    const bool layersApplied = mLayers && batch.in<Array::LayersApplied>();
    const auto resolveMoved = [&batch] {
      const std::vector<int>& moved = batch.in<Array::Moved>();
      return std::any_of(moved.begin(), moved.end(), [](int m) { return m > 0; });
    };
    const bool anyMoved = (resolve && resolveMoved()) || layersApplied || mSettles;
    if (!resolve || anyMoved) {
      countInside(mModel, batch, batch.in<Array::Shot>(), batch.in<Array::Cloth>(),
                  &FrameRecord::insideAfter, 0.0f, resolve && !layersApplied);
    }
    FrameRecord* records = batch.out<Array::Records>();
    for (int i = 0; i < batch.count(); ++i) {
      FrameRecord& record = records[i];
      if (resolve && !anyMoved) {
        record.insideAfter = record.insideCorrected;
      }
      if (!resolve) {
        record.insideCorrected = record.insideAfter;
      }
    }
  }

  Model& mModel;
  const bool mSwitches;                ///< binding switches: the correction's hits (world blending)
  const bool mLayers;                  ///< layers run before (they may have changed the cloth)
  const bool mSettles;                 ///< the settle stage runs before (SettleStage)
  std::vector<float> mPreviousOutput;  ///< the previous frame's cloth, 3Vd
  std::vector<SurfaceHit> mPreviousHits;  ///< its binding hits (world blending), Vd
};

}  // namespace

std::unique_ptr<Stage> makeAuditStage(Model& model) {
  if (!model.settings.audit) {
    return nullptr;
  }
  return std::make_unique<AuditStage>(model);
}

}  // namespace drivenshape::pipeline
