// SPDX-License-Identifier: Apache-2.0
// The glue of the host LayerBackend (host_layers.h): upload of the tables. The references are
// one file per kernel stem: host_mix.cpp (kernels/mix.cl) and host_wind.cpp (kernels/wind.cl).

#include "host_layers.h"

#include <memory>

#include "layer_checks.h"

namespace drivenshape {

void HostLayers::upload(const LayerTables& tables) {
  layer_checks::checkTables(tables);
  mTables = tables;
  mUploaded = true;
}

std::unique_ptr<LayerBackend> makeHostLayers() {
  return std::make_unique<HostLayers>();
}

}  // namespace drivenshape
