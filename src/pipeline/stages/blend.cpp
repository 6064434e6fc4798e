// SPDX-License-Identifier: Apache-2.0
// The blend (docs/method.md, "Blend"): the database shapes weighted per frame, on the backend. Per
// region when there are regions, then mixed per vertex with the regions' partition of unity.
// Local blending blends every shape's offsets in the local frames of the rest binding (encoded
// here, once); the bind baseline blends nothing and hands the rest shapes on.

#include <algorithm>

#include "local_encoding.h"
#include "parallel.h"

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class BlendStage final : public Stage {
 public:
  explicit BlendStage(Model& model) : mModel(model) {
    declare(Arrays().with(Array::Weights, model.settings.weightMode != WeightMode::kBind),
            {Array::Driven, Array::BlendedDriver});
    const Database& db = model.db;
    std::vector<float> localShapes;
    if (model.local) {
      // Bind once at rest (mask respected), then store every shape as offsets in the local
      // frames of the same triangles at the same barycentric points.
      model.restHits.resize(static_cast<std::size_t>(model.vd));
      model.binding().closest(1, db.driverMesh.positions.data(), db.drivenMesh.positions.data(),
                              model.restHits.data());
      model.restHitsBlock = model.device.makeArray();
      model.restHitsBlock.view(model.restHits.data(), model.restHits.size());
    }
    if (model.settings.weightMode == WeightMode::kModel) {
      uploadPoseModel();
      return;
    }
    if (model.local) {
      localShapes.resize(db.drivenShapes.size());
      parallelFor(model.k, model.threads, [&](int i) {
        encodeLocal(db.driverMesh, &db.driverShapes[i * model.driverValues], model.vd,
                    &db.drivenShapes[i * model.drivenValues], model.restHits.data(),
                    &localShapes[i * model.drivenValues]);
      });
    }
    // The backend's projection tables are those of the one QP on every (aligned) row.
    const bool regions = model.settings.regions.has_value();
    const std::unique_ptr<SimplexLeastSquares> full =
        regions ? std::make_unique<SimplexLeastSquares>(
                      driverMatrix(model.driverShapes, model.k, model.vp, {}))
                : nullptr;
    // The blended shapes are needed only on the backend from here on: hand them over.
    model.stages().upload(tablesFrom(db, full ? *full : *model.problems().front().solver,
                                     model.driverShapes,
                                     std::move(model.local ? localShapes : model.drivenShapes)));
  }

  const char* name() const override { return "blend"; }

  void run(Batch& batch) override {
    const int count = batch.count();
    const std::size_t dv = mModel.driverValues, dd = mModel.drivenValues;
    const bool needDriver = !mModel.local && mModel.settings.correct;
    DeviceArray& blended = batch.out<Array::Driven>();
    DeviceArray& blendedDriver = batch.out<Array::BlendedDriver>();
    blended.resize<float>(count * dd);
    blendedDriver.resize<float>(needDriver ? count * dv : 0);
    if (mModel.settings.weightMode == WeightMode::kModel) {
      // The rest offsets (weight 1) plus the basis shapes weighted by the pose stage.
      mModel.stages().blendBlock(count, batch.in<Array::Weights>().data(), blended, nullptr);
      return;
    }
    if (mModel.settings.weightMode == WeightMode::kBind) {
      // The rest shapes stand in for the blend: every frame binds the rest cloth to the rest
      // driver and carries it to the shot's pose.
      float* driven = blended.write<float>();
      float* driver = needDriver ? blendedDriver.write<float>() : nullptr;
      for (int i = 0; i < count; ++i) {
        std::copy_n(mModel.db.drivenMesh.positions.data(), dd, &driven[i * dd]);
        if (driver != nullptr) {
          std::copy_n(mModel.db.driverMesh.positions.data(), dv, &driver[i * dv]);
        }
      }
      return;
    }
    const int regionCount = mModel.regionCount();
    const float* weights = batch.in<Array::Weights>().data();
    if (regionCount == 1) {
      mModel.stages().blendBlock(count, weights, blended, needDriver ? &blendedDriver : nullptr);
      return;
    }
    mDrivenRegions.resize(static_cast<std::size_t>(count) * regionCount * dd);
    mDriverRegions.resize(needDriver ? mDrivenRegions.size() / dd * dv : 0);
    mModel.stages().blend(count * regionCount, weights, mDrivenRegions.data(),
                          needDriver ? mDriverRegions.data() : nullptr);
    const RegionSet& regions = *mModel.settings.regions;
    mix(count, mDrivenRegions, regions.drivenMix, mModel.vd, blended.write<float>());
    if (needDriver) {
      mix(count, mDriverRegions, regions.driverMix, mModel.vp, blendedDriver.write<float>());
    }
  }

 private:
  /// The pose model's tables: the rest cloth's offsets in the local frames of the rest binding,
  /// then the model's basis shapes (offsets in the same frames), blend-only.
  void uploadPoseModel() {
    const Database& db = mModel.db;
    const PoseModel& pose = db.poseModel;
    const std::size_t dd = mModel.drivenValues;
    ShapeTables tables;
    tables.driverVertexCount = mModel.vp;
    tables.drivenVertexCount = mModel.vd;
    tables.shapeCount = 1 + pose.rank();
    tables.drivenShapes.resize(static_cast<std::size_t>(tables.shapeCount) * dd);
    encodeLocal(db.driverMesh, db.driverMesh.positions.data(), mModel.vd,
                db.drivenMesh.positions.data(), mModel.restHits.data(), tables.drivenShapes.data());
    std::copy(pose.basis.begin(), pose.basis.end(), tables.drivenShapes.begin() + dd);
    mModel.stages().upload(tables);
  }

  /// out[f] = sum_r mix_r * perRegion[f][r], per vertex (the partition of unity).
  void mix(int count, const std::vector<float>& perRegion, const std::vector<float>& weightsOf,
           int vertices, float* out) const {
    const int regionCount = mModel.settings.regions->count();
    const std::size_t values = static_cast<std::size_t>(vertices) * 3;
    parallelFor(count, mModel.threads, [&](int i) {
      for (int v = 0; v < vertices; ++v) {
        double sum[3] = {0, 0, 0};
        for (int r = 0; r < regionCount; ++r) {
          const float phi = weightsOf[static_cast<std::size_t>(r) * vertices + v];
          const float* x =
              &perRegion[(static_cast<std::size_t>(i) * regionCount + r) * values + 3 * v];
          for (int c = 0; c < 3; ++c) {
            sum[c] += double(phi) * x[c];
          }
        }
        for (int c = 0; c < 3; ++c) {
          out[i * values + 3 * v + c] = static_cast<float>(sum[c]);
        }
      }
    });
  }

  Model& mModel;
  std::vector<float> mDrivenRegions, mDriverRegions;  ///< count x regions x 3V
};

}  // namespace

std::unique_ptr<Stage> makeBlendStage(Model& model) {
  return std::make_unique<BlendStage>(model);
}

}  // namespace drivenshape::pipeline
