// SPDX-License-Identifier: Apache-2.0
#pragma once

// Layering (docs/method.md, "Local frames, resolution, layers"): per-vertex weight maps, a
// per-vertex mix of the DrivenShape result with another cache (a simulated hood, a skinned mesh),
// and procedural wind that never pushes cloth into the body. The bake runs a LayerStack once per
// chunk of frames, after the correction.

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/layer_backend.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/weight_map.h>

namespace drivenshape {

class Hasher;  // src/core/hash.h, private

// ---- Settings ----

/// Every layer setting (plain data; the command line fills it with addLayerFlags).
struct LayerOptions {
  // Mix: out = w * drivenshape + (1 - w) * other, w = the mix weight map softened by mixFalloff.
  std::string mixCache;   ///< --mix: PC2 or EXR sequence with the driven mesh's vertex count;
                          ///< empty = no mix
  std::string mixWeight;  ///< --mix-weight: weight-map spec (see readWeightMap); 1 = DrivenShape
  int mixFalloff = 3;     ///< --mix-falloff: edge rings of the soft edge (0 = hard)

  // Wind: d = amplitude * weight * fractal value noise of the rest position advected along
  // `windDirection` at `windSpeed` (see kernels/layer_types.h), limited below the clearance.
  double windAmplitude = 0.0;  ///< --wind-amplitude: scene units (largest |d_c|); 0 = no wind
  double windFrequency = 1.0;  ///< --wind-frequency: noise cells per scene unit (1st octave)
  std::array<double, 3> windDirection = {1.0, 0.0, 0.0};  ///< --wind-direction, normalised
  double windSpeed = 1.0;      ///< --wind-speed: scene units per second the gusts travel
  int windOctaves = 3;         ///< --wind-octaves: 1..8, each twice the frequency, half the size
  std::uint32_t windSeed = 1;  ///< --wind-seed
  std::string windWeight;      ///< --wind-weight: weight-map spec; empty = 1 on every vertex
  int windFalloff = 0;         ///< --wind-falloff: edge rings softening the wind weight map

  /// Frames per second of the shot: wind time is frame / framesPerSecond (the bake's --fps).
  double framesPerSecond = 24.0;

  bool hasMix() const { return !mixCache.empty(); }
  bool hasWind() const { return windAmplitude > 0.0; }
};

// ---- The stack an evaluation runs ----

/// The layers of an evaluation as in-memory objects. `options` holds the numbers; its file
/// names and weight-map specs only name things in messages, the settings hash and the report.
/// An embedding application may fill `mixCache` and the weight vectors itself (names then
/// default to "(in memory)"); the command line fills them with loadLayers().
struct LayerSettings {
  LayerOptions options;
  /// The other cache of the cloth for the mix (same vertex count and order); null = no mix.
  std::shared_ptr<PointCacheReader> mixCache;
  /// Vd values in [0, 1]: 1 keeps DrivenShape, 0 takes the mix cache (falloff already applied).
  std::vector<float> mixWeights;
  /// Vd values in [0, 1] where the wind blows; empty = 1 everywhere (falloff already applied).
  std::vector<float> windWeights;

  bool hasMix() const { return mixCache != nullptr; }
  bool hasWind() const { return options.hasWind(); }
  bool empty() const { return !hasMix() && !hasWind(); }
};

/// Validates `options` (Error(kUsage) naming the flag) and loads what they name: the weight
/// maps (smoothed by their falloffs) and the mix cache (openPointCache with the driven mesh's
/// topology; Error(kInput) on another vertex count).
LayerSettings loadLayers(const LayerOptions& options, const Mesh& drivenMesh);

/// All layers of an evaluation, checked and uploaded once. The pipeline calls apply() once per
/// block of frames after the correction: mix first, then wind.
class LayerStack {
 public:
  /// Checks `settings` against the driven mesh (Error(kUsage) / Error(kInput)) and uploads the
  /// tables to `backend`, which must outlive the stack.
  LayerStack(LayerSettings settings, const Mesh& drivenMesh, LayerBackend& backend);

  /// True when no layer is on (apply() changes nothing).
  bool empty() const;
  /// Throws Error(kInput) naming the mix cache and the first missing frame.
  void checkFrames(const std::vector<int>& frames) const;
  /// Applies the layers to F frames in place. positions F x 3Vd; clearance F x Vd (may be null:
  /// the wind is then not limited).
  void apply(int frameCount, const int* frames, float* positions, const float* clearance);
  /// Adds every setting that changes the result (weights after falloff, not file names alone).
  void addToHash(Hasher& hasher) const;
  /// Compact JSON of the settings, "{}" when empty: for the bake report and the EXR header.
  std::string describe() const;

  const std::vector<float>& mixWeights() const { return mTables.mixWeights; }
  const std::vector<float>& windWeights() const { return mTables.windWeights; }

 private:
  LayerOptions mOptions;
  LayerTables mTables;
  WindSettings mWind;
  std::shared_ptr<PointCacheReader> mMixCache;
  LayerBackend& mBackend;
  std::vector<float> mOther;
};

}  // namespace drivenshape
