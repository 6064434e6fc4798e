// SPDX-License-Identifier: Apache-2.0
// Layers after the correction and resolution (docs/method.md, "Local frames, resolution, layers"):
// the mix with another cache, then wind limited by each vertex's clearance from the shot's driver
// (exact closest points, every triangle).

#include <cmath>

#include "../stage.h"
#include "json_text.h"

namespace drivenshape::pipeline {
namespace {

class LayersStage final : public Stage {
 public:
  explicit LayersStage(Model& model) : mModel(model) {
    const bool wind = model.settings.layers.hasWind();
    declare(Arrays{Array::Frames, Array::Cloth}.with(Array::Shot, wind),
            Arrays{Array::Cloth, Array::LayersApplied}.with(Array::AuditHits, wind));
    model.layerStack.emplace(model.settings.layers, model.db.drivenMesh, model.layers());
    if (model.settings.layers.hasWind()) {
      model.unmaskedClosest();  // the wind's clearance
    }
  }

  const char* name() const override { return "layers"; }

  void describe(nlohmann::json& settings) const override {
    settings["layers"] = parseJsonText(mModel.layerStack->describe(), "the layer description");
  }

  void run(Batch& batch) override {
    const std::size_t points = static_cast<std::size_t>(batch.count()) * mModel.vd;
    DeviceArray& cloth = batch.out<Array::Cloth>();
    mClearance.clear();
    if (mModel.settings.layers.hasWind()) {
      DeviceArray& auditHits = batch.out<Array::AuditHits>();
      auditHits.resize<SurfaceHit>(points);
      mModel.unmaskedClosest().closestBlock(batch.count(), batch.in<Array::Shot>(), cloth,
                                            auditHits);
      const SurfaceHit* hits = auditHits.read<SurfaceHit>();
      mClearance.resize(points);
      for (std::size_t i = 0; i < points; ++i) {
        mClearance[i] = std::sqrt(hits[i].distance2);
      }
    }
    // The layers run on the host copy (their backend takes host memory).
    mModel.layerStack->apply(batch.count(), batch.in<Array::Frames>() + batch.warm(),
                             cloth.modify<float>(),
                             mClearance.empty() ? nullptr : mClearance.data());
    batch.out<Array::LayersApplied>() = true;
  }

 private:
  Model& mModel;
  std::vector<float> mClearance;
};

}  // namespace

std::unique_ptr<Stage> makeLayersStage(Model& model) {
  if (model.settings.layers.empty()) {
    return nullptr;
  }
  return std::make_unique<LayersStage>(model);
}

}  // namespace drivenshape::pipeline
