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

#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

namespace drivenshape {

class Hasher;  // src/core/hash.h, private

// ---- Weight maps: one number in [0, 1] per driven vertex. ----

/// Reads a weight map for `driven` (Vd vertices) from `spec`, one of:
///
///   NAME.json           a JSON array of Vd numbers, [0.0, 1, 0.25, ...], or an object
///                       {"weights": [...]} (other keys: "comment" only)
///   NAME.exr            a one-channel point-cache EXR: channel W (or the file's only channel
///                       besides A) in the point-cache pixel layout, vertex v at pixel
///                       (v mod width, v div width), with dsVertexCount = Vd (writeWeightMapExr)
///   group:NAME[,NAME]   the `g`/`o` face groups of the driven OBJ: weight 1 on every vertex of
///                       their faces, 0 elsewhere (soften the edge with a falloff)
///
/// `what` names the map in messages ("--mix-weight"). Throws Error(kInput) naming the file and
/// the index for a wrong length, a value outside [0, 1], NaN or a non-number, and for an
/// unknown group (listing the known ones); Error(kUsage) for a spec of no known form.
std::vector<float> readWeightMap(const std::string& spec, const Mesh& driven,
                                 const std::string& what = "weight map");

/// Writes a weight map as a one-channel point-cache EXR (channel W, coverage A, dsVertexCount),
/// atomically, `width` pixels per row. Throws Error(kInput) for values outside [0, 1].
void writeWeightMapExr(const std::string& path, const std::vector<float>& weights,
                       int width = 1024);

/// The map softened across `rings` edge rings of `mesh`: each vertex gets the average of the
/// values within `rings` edges of it, weighted by (rings + 1 - edge distance), computed in
/// double. A vertex whose neighbourhood holds one value keeps it bitwise, so values more than
/// `rings` rings from any change are exact (weight 1 stays exactly 1). Across a straight
/// boundary of a regular mesh the result is monotone (a convolution of a step with a positive
/// kernel). rings = 0 returns the map unchanged. Throws Error(kUsage) for rings outside 0..64.
std::vector<float> smoothWeightMap(const std::vector<float>& weights, const Mesh& mesh, int rings);

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

/// The per-frame wind parameters a backend needs, derived from LayerOptions for one frame:
/// see windFrameOffsets.
struct WindSettings {
  float amplitude = 0.0f;  ///< scene units
  float frequency = 1.0f;
  std::array<double, 3> direction = {1.0, 0.0, 0.0};  ///< unit
  double speed = 0.0;
  int octaves = 1;
  std::uint32_t seed = 1;
  double framesPerSecond = 24.0;
};

/// The per-vertex tables a LayerBackend keeps between calls (Vd vertices).
///
///   rest         3Vd floats  rest positions minus their bounding-box centre (the noise domain)
///   mixWeights   Vd floats   in [0, 1]; empty when there is no mix
///   windWeights  Vd floats   in [0, 1]; empty when there is no wind
struct LayerTables {
  int vertexCount = 0;
  std::vector<float> rest;
  std::vector<float> mixWeights;
  std::vector<float> windWeights;
};

/// The layer kernels for chunks of F frames. Two implementations share this contract: OpenCL
/// (makeClLayers: kernels/mix.cl, kernels/wind.cl) and the host reference (makeHostLayers).
/// Frame blocks are frame-major float32:
///
///   positions, other  F x 3Vd   vertex v of frame f, axis a at [f * 3Vd + 3v + a]
///   clearance         F x Vd    unsigned distance of vertex v to the driver surface of frame f
///
/// upload() once (again to replace the tables), then mix()/wind() many times; calling them
/// before upload() throws Error(kInternal). Not thread-safe.
class LayerBackend {
 public:
  virtual ~LayerBackend() = default;
  /// "host" or the OpenCL device name.
  virtual std::string name() const = 0;
  virtual void upload(const LayerTables& tables) = 0;
  /// positions = w * positions + (1 - w) * other per vertex (w = tables.mixWeights); vertices
  /// with w = 1 keep their positions bitwise, w = 0 take `other` bitwise.
  virtual void mix(int frameCount, const float* other, float* positions) = 0;
  /// Adds the wind displacement of frame frames[f] to frame f of `positions`, scaled by
  /// tables.windWeights and, when `clearance` is not null, limited below the clearance. A pure
  /// function of (frame, vertex): chunking never changes the result.
  virtual void wind(int frameCount, const int* frames, const WindSettings& settings,
                    const float* clearance, float* positions) = 0;
};

std::unique_ptr<LayerBackend> makeHostLayers();

/// Octave advection offsets of one frame: for octave o (DS_WIND_MAX_OCTAVES x 4 floats, xyz
/// used), -(2^o frequency speed frame/fps) direction + a fixed per-octave decorrelation shift,
/// reduced modulo the lattice period in double. Shared by both backends.
void windFrameOffsets(const WindSettings& settings, int frame, float* offsets);

/// The largest frame-to-frame change of a wind displacement (before the weight, which scales
/// it, and the clearance limit, which can only shrink it), per second of shot time:
///   |d(t2) - d(t1)| <= windRateBound(settings) * |t2 - t1|.
/// Derivation: each octave o is value noise at 2^o f (p - s t u); its slope is at most 3.75 per
/// lattice axis, so |d n / d t| <= 3.75 sqrt(3) 2^o f s; the octave gains 0.5^o normalised by
/// their sum S make that 3.75 sqrt(3) f s O / S per channel, and sqrt(3) channels of the
/// amplitude A give 11.25 A f s O / S.
double windRateBound(const WindSettings& settings);

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
