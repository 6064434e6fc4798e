// SPDX-License-Identifier: Apache-2.0
// Argument checks shared by the two LayerBackend implementations, so both refuse the same
// calls with the same messages. Private to src/devices.

#pragma once

#include <drivenshape/error.h>
#include <drivenshape/layer_backend.h>

namespace drivenshape::layer_checks {

inline void checkTables(const LayerTables& tables) {
  const auto count = static_cast<std::size_t>(tables.vertexCount);
  if (tables.vertexCount <= 0 || tables.rest.size() != 3 * count ||
      (!tables.mixWeights.empty() && tables.mixWeights.size() != count) ||
      (!tables.windWeights.empty() && tables.windWeights.size() != count)) {
    DS_THROW(kInternal, "LayerBackend::upload: inconsistent tables (", tables.vertexCount,
             " vertices, ", tables.rest.size(), " rest floats, ", tables.mixWeights.size(),
             " mix weights, ", tables.windWeights.size(), " wind weights)");
  }
}

inline void checkCall(const char* what, bool uploaded, bool hasWeights, int frameCount) {
  if (!uploaded) {
    DS_THROW(kInternal, "LayerBackend::", what, " called before upload()");
  }
  if (!hasWeights) {
    DS_THROW(kInternal, "LayerBackend::", what, " called without ", what, " weights uploaded");
  }
  if (frameCount < 0) {
    DS_THROW(kInternal, "LayerBackend::", what, " called with ", frameCount, " frames");
  }
}

inline void checkWind(const WindSettings& settings) {
  if (settings.octaves < 1 || settings.octaves > 8 || !(settings.framesPerSecond > 0.0) ||
      !(settings.amplitude >= 0.0f) || !(settings.frequency > 0.0f)) {
    DS_THROW(kInternal, "LayerBackend::wind: bad settings (", settings.octaves, " octaves, fps ",
             settings.framesPerSecond, ", amplitude ", settings.amplitude, ", frequency ",
             settings.frequency, ")");
  }
}

}  // namespace drivenshape::layer_checks
