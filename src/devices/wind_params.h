// SPDX-License-Identifier: Apache-2.0
// The scalars of one wind launch, made the same way for both backends. Private to src/devices.

#pragma once

#include <cmath>

#include <drivenshape/layer_backend.h>
#include <layer_types.h>

namespace drivenshape::layer_detail {

/// Kernel parameters for `settings`; the amplitude is divided by the sum of the octave gains
/// (sum_o 0.5^o) so that no channel of the displacement exceeds the user's amplitude.
inline DsWindParams makeWindParams(const WindSettings& settings, int vertexCount, int frameCount,
                                   bool hasClearance) {
  double gains = 0.0;
  for (int o = 0; o < settings.octaves; ++o) {
    gains += std::ldexp(1.0, -o);
  }
  DsWindParams params{};
  params.vertexCount = vertexCount;
  params.frameCount = frameCount;
  params.octaves = settings.octaves;
  params.seed = settings.seed;
  params.amplitude = static_cast<float>(static_cast<double>(settings.amplitude) / gains);
  params.frequency = settings.frequency;
  params.hasClearance = hasClearance ? 1 : 0;
  return params;
}

}  // namespace drivenshape::layer_detail
