// SPDX-License-Identifier: Apache-2.0
// Rigid alignment (AlignMode::kRigid, kRigidAll): each driver frame is fitted to the database's
// rest driver, and so is every database shape (once, here), so that the weights and the blend
// compare poses, not places. The correction (or the inverse motion) takes the cloth back.

#include "parallel.h"

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class AlignStage final : public Stage {
 public:
  explicit AlignStage(Model& model) : mModel(model) {
    declare({Array::Driver}, {Array::Aligned, Array::Motions, Array::Records});
    const Database& db = model.db;
    const EvaluatorSettings& settings = model.settings;
    const std::string source =
        "align group '" + (settings.alignGroup.empty() ? std::string("all") : settings.alignGroup) +
        "' (driver mesh)";
    model.alignVertices = selectVertices(db.driverMesh, settings.alignGroup, source);
    model.aligner = std::make_unique<RigidAligner>(db.driverMesh, db.driverMesh.positions.data(),
                                                   model.alignVertices, source);
    if (settings.align == AlignMode::kRigid) {
      // Lock onto the part that moves rigidly across the database (the pelvis, not the legs).
      RigidityOptions rigidity;
      rigidity.threads = model.threads;
      model.aligner->weightByRigidity(db.driverShapes.data(), model.k, rigidity);
    }
    // The database in the same frame as the shots: each shape pair moves with the motion that
    // fits its driver shape to the rest driver.
    const std::size_t dv = model.driverValues, dd = model.drivenValues;
    parallelFor(model.k, model.threads, [&](int i) {
      const RigidTransform motion = model.aligner->fit(&db.driverShapes[i * dv]);
      motion.apply(&db.driverShapes[i * dv], model.vp, &model.driverShapes[i * dv]);
      if (!model.local) {
        motion.apply(&db.drivenShapes[i * dd], model.vd, &model.drivenShapes[i * dd]);
      }
    });
  }

  const char* name() const override { return "align"; }

  void describe(nlohmann::json& settings) const override {
    settings["align_vertices"] = mModel.alignVertices.size();
  }

  void run(Batch& batch) override {
    const std::size_t dv = mModel.driverValues;
    const float* driver = batch.in<Array::Driver>();
    float* aligned = batch.writeAligned(static_cast<std::size_t>(batch.solveCount()) * dv);
    std::vector<RigidTransform>& motions = batch.out<Array::Motions>();
    motions.resize(batch.solveCount());
    parallelFor(batch.solveCount(), mModel.threads, [&](int i) {
      motions[i] = mModel.aligner->fit(&driver[i * dv]);
      motions[i].apply(&driver[i * dv], mModel.vp, &aligned[i * dv]);
    });
    FrameRecord* records = batch.out<Array::Records>();
    for (int i = 0; i < batch.count(); ++i) {
      const RigidTransform& motion = motions[batch.warm() + i];
      FrameRecord& record = records[i];
      record.alignRotation.clear();
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
          record.alignRotation.push_back(motion.rotation(r, c));
        }
      }
      record.alignTranslation.assign(motion.translation.data(), motion.translation.data() + 3);
    }
  }

 private:
  Model& mModel;
};

}  // namespace

std::unique_ptr<Stage> makeAlignStage(Model& model) {
  if (model.settings.weightMode == WeightMode::kBind ||
      model.settings.weightMode == WeightMode::kModel || model.settings.align == AlignMode::kNone) {
    return nullptr;
  }
  return std::make_unique<AlignStage>(model);
}

}  // namespace drivenshape::pipeline
