// SPDX-License-Identifier: Apache-2.0
// The host reference of kernels/wind.cl: HostLayers::wind (host_layers.h). Also the per-frame
// wind offsets and the continuity bound, which both backends share.

#include "host_layers.h"

#include <cmath>
#include <cstddef>

#include <layer_types.h>

#include "layer_checks.h"
#include "wind_params.h"

namespace drivenshape {

void HostLayers::wind(int frameCount, const int* frames, const WindSettings& settings,
                      const float* clearance, float* positions) {
  layer_checks::checkCall("wind", mUploaded, !mTables.windWeights.empty(), frameCount);
  layer_checks::checkWind(settings);
  const DsWindParams params =
      layer_detail::makeWindParams(settings, mTables.vertexCount, frameCount, clearance != nullptr);
  const std::size_t count = static_cast<std::size_t>(mTables.vertexCount);
  float offsets[DS_WIND_MAX_OCTAVES * 4];
  for (std::size_t f = 0; f < static_cast<std::size_t>(frameCount); ++f) {
    windFrameOffsets(settings, frames[f], offsets);
    for (std::size_t v = 0; v < count; ++v) {
      const float weight = mTables.windWeights[v];
      if (weight == 0.0f) {
        continue;
      }
      float displacement[3];
      dsWindDisplacement(&mTables.rest[3 * v], offsets, params, displacement);
      const float c = clearance != nullptr ? clearance[f * count + v] : 0.0f;
      dsWindApply(positions + f * 3 * count + 3 * v, displacement, weight, c, params.hasClearance);
    }
  }
}

void windFrameOffsets(const WindSettings& settings, int frame, float* offsets) {
  const double time = static_cast<double>(frame) / settings.framesPerSecond;
  const double travel = static_cast<double>(settings.frequency) * settings.speed * time;
  // Irrational-ish shifts so the octaves do not share a lattice origin (a visible pole at 0).
  constexpr double kDecorrelation[3] = {37.1731, 11.8357, 53.4129};
  for (int o = 0; o < DS_WIND_MAX_OCTAVES; ++o) {
    const double scale = std::ldexp(1.0, o);
    for (int a = 0; a < 3; ++a) {
      const double offset =
          -scale * travel * settings.direction[static_cast<std::size_t>(a)] + kDecorrelation[a] * o;
      const double period = DS_WIND_PERIOD;
      offsets[4 * o + a] = static_cast<float>(offset - period * std::floor(offset / period));
    }
    offsets[4 * o + 3] = 0.0f;
  }
}

double windRateBound(const WindSettings& settings) {
  double gains = 0.0;
  for (int o = 0; o < settings.octaves; ++o) {
    gains += std::ldexp(1.0, -o);
  }
  return 11.25 * static_cast<double>(settings.amplitude) * static_cast<double>(settings.frequency) *
         settings.speed * settings.octaves / gains;
}

}  // namespace drivenshape
