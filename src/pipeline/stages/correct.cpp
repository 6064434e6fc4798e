// Onto the shot's driver (DESIGN.md §3 steps 5-6). Local blending rebuilds the blended offsets
// on the shot's driver; world blending binds the blended cloth D~ to the blended driver P~
// (exact closest triangles, mask respected) and carries it to the shot's driver in each
// triangle's frame. Without the correction the cloth only goes back through the inverse
// alignment.

#include <algorithm>

#include "parallel.h"

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class CorrectStage final : public Stage {
 public:
  explicit CorrectStage(Model& model) : mModel(model) {
    if (model.settings.correct) {
      model.binding();  // made now, so that it holds each batch's shot driver (keepShotPoses)
    }
  }

  const char* name() const override { return "correct"; }

  void addToHash(Hasher& hasher) const override {
    const BindingMask& mask = mModel.mask();
    hasher.addValue(mModel.settings.correct);
    for (int c = 0; c < mask.classCount(); ++c) {
      hasher.add(mask.classTriangles(c).data(), mask.classTriangles(c).size() * sizeof(int));
    }
    hasher.add(mask.vertexClasses().data(), mask.vertexClasses().size() * sizeof(int));
  }

  void run(Batch& batch) override {
    const int count = batch.count;
    const float* shotDriver = batch.driverBlock(mModel.driverValues);
    if (mModel.local) {
      mModel.binding().rebuild(count, mModel.restHits.data(), shotDriver, batch.driven.data(),
                               batch.cloth);
    } else if (mModel.settings.correct) {
      batch.hits.resize(static_cast<std::size_t>(count) * mModel.vd);
      mModel.binding().closest(count, batch.blendedDriver.data(), batch.driven.data(),
                               batch.hits.data());
      // P~ is in the aligned frame, the shot's driver in world space: the transfer carries the
      // cloth through the inverse alignment too.
      mModel.binding().transfer(count, batch.hits.data(), batch.blendedDriver.data(), shotDriver,
                                batch.driven.data(), batch.cloth);
    } else if (mModel.aligner) {
      const std::size_t dd = mModel.drivenValues;
      parallelFor(count, mModel.threads, [&](int i) {
        batch.motions[batch.warm + i].applyInverse(&batch.driven[i * dd], mModel.vd,
                                                   &batch.cloth[i * dd]);
      });
    } else {
      std::copy(batch.driven.begin(), batch.driven.end(), batch.cloth);
    }
  }

 private:
  Model& mModel;
};

}  // namespace

std::unique_ptr<Stage> makeCorrectStage(Model& model) {
  return std::make_unique<CorrectStage>(model);
}

}  // namespace drivenshape::pipeline
