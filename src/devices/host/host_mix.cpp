// SPDX-License-Identifier: Apache-2.0
// The host reference of kernels/mix.cl: HostLayers::mix (host_layers.h).

#include "host_layers.h"

#include <cstddef>

#include "layer_checks.h"

namespace drivenshape {

void HostLayers::mix(int frameCount, const float* other, float* positions) {
  layer_checks::checkCall("mix", mUploaded, !mTables.mixWeights.empty(), frameCount);
  const std::size_t count = static_cast<std::size_t>(mTables.vertexCount);
  for (std::size_t f = 0; f < static_cast<std::size_t>(frameCount); ++f) {
    for (std::size_t v = 0; v < count; ++v) {
      const float w = mTables.mixWeights[v];
      if (w == 1.0f) {
        continue;
      }
      const std::size_t at = f * 3 * count + 3 * v;
      for (std::size_t a = 0; a < 3; ++a) {
        positions[at + a] =
            w == 0.0f ? other[at + a] : w * positions[at + a] + (1.0f - w) * other[at + a];
      }
    }
  }
}

}  // namespace drivenshape
