// SPDX-License-Identifier: Apache-2.0
// Strain limit (docs/method.md, "Strain limit"): after the correction and before the penetration
// resolution, each frame's cloth edges are brought back into the band [(1 - s) L, (1 + s) L]
// around their rest lengths L by Chebyshev-accelerated Jacobi iterations of edge projections
// (StrainLimitBackend, src/devices/strain_limit.h), every frame alone. The garment's open
// borders and a layer under the skin (a muscle) stay as they are; every other vertex may move.
// With the resolution on, each cloth vertex near the skin is kept in front of its skin plane
// through the iterations (ClosestBackend::skinPlanes): the limit slides the cloth along the body
// instead of pulling it in, and a vertex shallowly inside comes out within the limit, its edges
// following it. The resolution after it puts back out of the body whatever is still in.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <drivenshape/binding.h>
#include <drivenshape/mesh.h>

#include "../stage.h"
#include "strain_limit.h"

namespace drivenshape::pipeline {
namespace {

/// The relaxation of the Jacobi iterations: each vertex moves by this over its edge count times
/// the sum of its edges' corrections (StrainLimitTables). Above 1 reaches the band in fewer
/// iterations; below 2 keeps the iterations stable. On the sleeve sample (band 3%, 30
/// iterations) mean |strain| 3.7% at 1, 3.4% at 1.5, 3.2% at 1.9.
constexpr double kStrainRelaxation = 1.5;

/// Chebyshev acceleration of the iterations (StrainLimitTables): the estimated spectral radius
/// of the plain iteration and the first accelerated iteration. Chosen on the validation clips
/// (docs/validation.md, "Strain"): with 30 iterations and a 1% band the garments' mean |strain|
/// falls from 2.2-3.9% (plain) to 1.0-2.1% at 0.98 (independent numpy study of the same
/// iteration on the bakes of four clips); 0.99 goes lower still but leaves less margin against
/// oscillation. From the second iteration (the first has no iteration before it) rather than
/// the fifth: 24 iterations then leave the 18 validation clips less stretched than 30 from the
/// fifth (the highest mean |strain| 1.08 x the simulation's against 1.09 x), and meet the same
/// bars (docs/validation.md, "Fewer iterations").
constexpr double kChebyshevRadius = 0.98;
constexpr int kChebyshevFrom = 2;

/// The gain of the corrections that lengthen a short edge (StrainLimitTables::compression).
/// Pushing a compressed edge's ends apart along it amplifies any sideways offset between them
/// (the edge buckles), and the acceleration amplifies that mode further: at 1 the sample's
/// bake moved by 1.65e-4 of its diagonal when the shot was moved rigidly through the world
/// (its float rounding, 9e-6 without the limit, amplified 18 times; test_bake_fidelity bounds it
/// at 1e-4), 1.1e-4 at 0.7, 9.1e-5 at 0.6 and 6.5e-5 at 0.5. Widening the band on that side
/// instead lost strain bars (docs/validation.md, "The limit's conditioning"); at 0.5 with an
/// exit fade of 0.25 every bar of the validation table holds.
constexpr double kStrainCompression = 0.5;

/// The skin planes' reach, in skin offsets (EvaluatorSettings::skinOffset): a vertex at this
/// signed distance from the skin or farther before the limit gets no plane (the clearance
/// certificate answers most of them without a search; the planes do not depend on which). 2
/// offsets, 4 mm at the default offset: the validation clips met the same bars with 2, 3 and 5
/// (docs/validation.md, "Strain"), and fewer vertices to search make the limit cheaper.
constexpr double kPlaneReach = 2.0;

/// How far a vertex may move in the limit, in skin offsets, and keep the answer the certificate
/// gave it before (ResolveStage): kPlaneReach - 1 leaves it at least an offset clear.
constexpr double kKeptReach = kPlaneReach - 1.0;

/// How deep inside the body, in skin offsets, a vertex still gets its full plane (and so comes out
/// within the limit); deeper, the plane sinks away until there is none at 1.5 times this
/// (ClosestBackend::skinPlanes). Deeper ones are left to the limit, which pulls them back
/// towards their neighbours, and then to the resolution: moved out first, a vertex 10 cm deep in
/// the trousers' crotch stays on the far side of the leg the resolution chose, and jumps when
/// that side changes. Chosen on the validation clips (docs/validation.md, "Strain"): cut off at
/// once, 7.5 offsets (1.5 cm) met every bar of issue 43 on 9 of the 16 validation clips, against
/// 6 at 0.5 cm, 7 at 1 cm and 8 at 2.5 cm; the fade beyond it took the largest jump of one clip
/// back down by 15 mm.
constexpr double kPlaneDepth = 7.5;

/// The strain limit's vertex weights: 0 holds a vertex where the pipeline put it, 1 lets it move.
/// Held: the garment's open borders (borderVertices: a hem, a cuff, a waistband), where the cloth
/// swings freest and fastest; moved, a border vertex spreads its edges' stretch along the border,
/// which changes the largest frame-to-frame jump by a fraction of a millimetre either way (held,
/// the validation clips' largest jumps are the defaults' to the 0.1 mm; moved, five of 18 rose
/// by 0.1-0.4 mm: docs/validation.md, "Held borders"). Their edges still pull the vertices next
/// to them. Held too: a vertex that lives under the skin (a muscle or fat layer, Model::sides),
/// since such a layer stretches and shrinks with the skin by design. Every other cloth vertex
/// may move. Empty (every vertex 1) when none is held.
std::vector<float> movingVertices(Model& model) {
  const std::vector<int> border = borderVertices(model.db.drivenMesh);
  if (border.empty() && model.insideVertices() == 0) {
    return {};
  }
  std::vector<float> weights(static_cast<std::size_t>(model.vd), 1.0f);
  for (const int v : border) {
    weights[static_cast<std::size_t>(v)] = 0.0f;
  }
  if (model.insideVertices() > 0) {
    const std::vector<std::int8_t>& sides = model.sides();
    for (std::size_t v = 0; v < sides.size(); ++v) {
      if (sides[v] == kSideInside) {
        weights[v] = 0.0f;
      }
    }
  }
  return weights;
}

class StrainLimitStage final : public Stage {
 public:
  explicit StrainLimitStage(Model& model) : mModel(model), mPlanes(limitsWithSkinPlanes(model)) {
    if (mPlanes) {
      declare({Array::Shot, Array::Cloth}, kAuditArrays | Arrays{Array::SkinPlanes, Array::Cloth});
      model.sides();
    } else {
      declare({Array::Cloth}, {Array::Cloth});
    }
    mBackend = model.device.makeStrainLimit(model.threads);
    const int iterations = model.settings.strainIterations;
    mBackend->upload(strainLimitTables(
        model.db.drivenMesh, model.settings.strainLimit, iterations, kStrainRelaxation,
        chebyshevWeights(iterations, kChebyshevRadius, kChebyshevFrom), movingVertices(model),
        kStrainCompression));
  }

  const char* name() const override { return "strain"; }

  void run(Batch& batch) override {
    DeviceArray& cloth = batch.out<Array::Cloth>();
    if (!mPlanes) {
      mBackend->limitBlock(batch.count(), cloth, nullptr, nullptr, 0.0f);
      return;
    }
    const int count = batch.count();
    const float offset = static_cast<float>(mModel.settings.skinOffset);
    DeviceArray& shot = batch.in<Array::Shot>();
    // A point the certificate answers here at kPlaneReach offsets, for every point within
    // kKeptReach offsets of it, is still an offset clear, on its side, after the limit moved it
    // less than that: the resolution keeps its answer (ResolveStage). The limit's marks take a
    // reach a little shorter, for the device's float arithmetic of the distance moved.
    const float reach = static_cast<float>(kKeptReach * offset);
    const float clearance = static_cast<float>(kPlaneReach * offset);
    DeviceArray* marks =
        findSkinPlanes(mModel, batch, shot, cloth, clearance, offset,
                       static_cast<float>(kPlaneDepth * offset), /*keep=*/false, reach);
    mBackend->limitBlock(count, cloth, &batch.out<Array::SkinPlanes>(), marks,
                         reach * (1.0f - 1e-4f));
  }

 private:
  Model& mModel;
  bool mPlanes = false;  ///< with the resolution on: the skin planes
  std::unique_ptr<StrainLimitBackend> mBackend;
};

}  // namespace

bool limitsWithSkinPlanes(const Model& model) {
  return model.settings.strainLimit > 0 && model.settings.resolve;
}

std::unique_ptr<Stage> makeStrainLimitStage(Model& model) {
  if (!(model.settings.strainLimit > 0)) {
    return nullptr;
  }
  return std::make_unique<StrainLimitStage>(model);
}

}  // namespace drivenshape::pipeline
