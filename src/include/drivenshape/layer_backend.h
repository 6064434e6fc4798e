// SPDX-License-Identifier: Apache-2.0
#pragma once

// The layer kernels' contract (mix and wind) that each device implements, and the per-frame wind
// parameters both backends derive the same way. The layers themselves: drivenshape/layers.h.

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace drivenshape {

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

}  // namespace drivenshape
