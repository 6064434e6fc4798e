// SPDX-License-Identifier: Apache-2.0
#pragma once

// The host reference of the per-frame stages (private to the devices room): the class
// HostStages, whose members are defined one file per kernel stem. host_stages.cpp holds the glue
// (upload), host_project.cpp the reference of kernels/project.cl, host_blend.cpp that of
// kernels/blend.cl. Plain loops, every sum in double, one rounding to float at the end: the
// oracle the OpenCL kernels are tested against, so it favours obviousness over speed.

#include <string>
#include <vector>

#include "stages.h"

namespace drivenshape {

class HostStages final : public StageBackend {
 public:
  std::string name() const override { return "host"; }

  void upload(const ShapeTables& tables) override;
  void project(int frameCount, const float* driverFrames, float* projections,
               float* norms) override;
  void blend(int frameCount, const float* weights, float* driven, float* driver) override;

 private:
  void blendShapes(int frameCount, const float* weights, const std::vector<float>& shapes,
                   int vertexCount, float* out);

  ShapeTables mTables;
  bool mUploaded = false;
  std::vector<double> mAccumulator;
};

}  // namespace drivenshape
