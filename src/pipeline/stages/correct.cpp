// SPDX-License-Identifier: Apache-2.0
// Onto the shot's driver (docs/method.md, "Local frames, resolution, layers"). Local blending
// rebuilds the blended offsets on the shot's driver; world blending binds the blended cloth D~ to
// the blended driver P~ (exact closest triangles, mask respected) and carries it to the shot's
// driver in each triangle's frame. Without the correction the cloth only goes back through the
// inverse alignment.

#include <algorithm>

#include "parallel.h"

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class CorrectStage final : public Stage {
 public:
  explicit CorrectStage(Model& model) : mModel(model) {
    if (model.local) {
      declare({Array::Shot, Array::Driven}, {Array::Cloth});
    } else if (model.settings.correct) {
      declare({Array::Shot, Array::Driven, Array::BlendedDriver}, {Array::Hits, Array::Cloth});
    } else {
      declare(Arrays{Array::Driven}.with(Array::Motions, model.aligner != nullptr), {Array::Cloth});
    }
    if (model.settings.correct) {
      model.binding();
    }
  }

  const char* name() const override { return "correct"; }

  void run(Batch& batch) override {
    const int count = batch.count();
    DeviceArray& blended = batch.in<Array::Driven>();
    DeviceArray& cloth = batch.out<Array::Cloth>();
    if (mModel.local) {
      mModel.binding().rebuildBlock(count, mModel.restHitsBlock, batch.in<Array::Shot>(), blended,
                                    cloth);
    } else if (mModel.settings.correct) {
      DeviceArray& hits = batch.out<Array::Hits>();
      DeviceArray& blendedDriver = batch.in<Array::BlendedDriver>();
      hits.resize<SurfaceHit>(static_cast<std::size_t>(count) * mModel.vd);
      mModel.binding().closestBlock(count, blendedDriver, blended, hits);
      // P~ is in the aligned frame, the shot's driver in world space: the transfer carries the
      // cloth through the inverse alignment too.
      mModel.binding().transferBlock(count, hits, blendedDriver, batch.in<Array::Shot>(), blended,
                                     cloth);
    } else {
      // No correction: the blend is the cloth, taken back through the inverse alignment.
      const float* driven = blended.read<float>();
      float* out = cloth.write<float>();
      const std::size_t dd = mModel.drivenValues;
      if (mModel.aligner) {
        const std::vector<RigidTransform>& motions = batch.in<Array::Motions>();
        parallelFor(count, mModel.threads, [&](int i) {
          motions[batch.warm() + i].applyInverse(&driven[i * dd], mModel.vd, &out[i * dd]);
        });
      } else {
        std::copy_n(driven, static_cast<std::size_t>(count) * dd, out);
      }
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
