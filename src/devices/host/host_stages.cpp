// SPDX-License-Identifier: Apache-2.0
// The glue of the host per-frame stages (host_stages.h): upload of the tables. The references
// are one file per kernel stem: host_project.cpp (kernels/project.cl) and host_blend.cpp
// (kernels/blend.cl).

#include "host_stages.h"

#include <memory>

#include "stage_checks.h"

namespace drivenshape {

void HostStages::upload(const ShapeTables& tables) {
  stage_checks::checkTables(tables);
  mTables = tables;
  mUploaded = true;
}

std::unique_ptr<StageBackend> makeHostStages() {
  return std::make_unique<HostStages>();
}

}  // namespace drivenshape
