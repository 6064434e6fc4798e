// SPDX-License-Identifier: Apache-2.0
#pragma once

// The host reference of the layer kernels (private to the devices room): the class HostLayers,
// whose members are defined one file per kernel stem. host_layers.cpp holds the glue (upload),
// host_mix.cpp the reference of kernels/mix.cl, host_wind.cpp that of kernels/wind.cl (with the
// per-frame wind offsets and the continuity bound, which both backends share). The same shared
// functions of kernels/layer_types.h, one vertex at a time.

#include <string>

#include <drivenshape/layer_backend.h>

namespace drivenshape {

class HostLayers final : public LayerBackend {
 public:
  std::string name() const override { return "host"; }

  void upload(const LayerTables& tables) override;
  void mix(int frameCount, const float* other, float* positions) override;
  void wind(int frameCount, const int* frames, const WindSettings& settings, const float* clearance,
            float* positions) override;

 private:
  LayerTables mTables;
  bool mUploaded = false;
};

}  // namespace drivenshape
