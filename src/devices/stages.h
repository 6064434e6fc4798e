// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "device_array.h"

namespace drivenshape {

/// Flat, backend-neutral tables built once per bake from a database (the "far" side:
/// precompute once, evaluate many frames). All float32, row-major:
///
///   projectionRows  (k-1) x 3Vp   row r = column r of M = A Z (see SimplexLeastSquares)
///   center          3Vp           m, the mean driver shape
///   driverShapes    k x 3Vp       database driver shapes P_i, interleaved xyz
///   drivenShapes    k x 3Vd       database driven shapes D_i, interleaved xyz
struct ShapeTables {
  int driverVertexCount = 0;  ///< Vp
  int drivenVertexCount = 0;  ///< Vd
  int shapeCount = 0;         ///< k
  std::vector<float> projectionRows;
  std::vector<float> center;
  std::vector<float> driverShapes;
  std::vector<float> drivenShapes;
  /// Blend-only tables (the pose model's basis): driven shapes alone, no projection, center or
  /// driver shapes; project() and a driver blend are then errors.
  bool blendOnly() const {
    return projectionRows.empty() && center.empty() && driverShapes.empty();
  }
};

/// The per-frame stages of a bake, evaluated for a chunk of F frames per call (the "osd"
/// side). Two implementations share this contract: the OpenCL kernels (makeClStages, in
/// src/devices/cl) and the plain C++ host reference (makeHostStages), which is the
/// oracle in tests. Frame blocks are frame-major:
///
///   frames   F x 3V   frame f, vertex v, axis a at [f * 3V + 3v + a]
///   weights  F x k
///
/// upload() is called once (again to replace the tables), then project()/blend() many times;
/// calling them before upload() throws Error(kInternal). Not thread-safe.
class StageBackend {
 public:
  virtual ~StageBackend() = default;
  /// "host" or the OpenCL device name.
  virtual std::string name() const = 0;
  /// Makes the tables resident (device memory for OpenCL). Must precede the other calls.
  virtual void upload(const ShapeTables& tables) = 0;

  /// For each frame b (driver positions): projections[f] = M^T (b - m)   (k-1 values) and
  /// norms[f] = { ||b - m||^2, ||b||^2 }.
  ///   driverFrames  F x 3Vp;  projections  F x (k-1) (may be null when k = 1);  norms  F x 2
  virtual void project(int frameCount, const float* driverFrames, float* projections,
                       float* norms) = 0;

  /// Blends the database shapes with per-frame weights (any linear combination; the bake's
  /// weights sum to 1):
  ///   driven[f] = sum_i weights[f][i] D_i    (F x 3Vd)
  ///   driver[f] = sum_i weights[f][i] P_i    (F x 3Vp; skipped when `driver` is null)
  virtual void blend(int frameCount, const float* weights, float* driven, float* driver) = 0;

  // The same on DeviceArrays (drivenshape/device_array.h), for a block of frames that stays on
  // the device between stages: an OpenCL backend reads and writes the arrays' device memory and
  // copies nothing back; the defaults work on the host copies through the calls above.
  /// project() of `driverFrames` (F x 3Vp floats).
  virtual void projectBlock(int frameCount, DeviceArray& driverFrames, float* projections,
                            float* norms) {
    project(frameCount, driverFrames.read<float>(), projections, norms);
  }
  /// blend() into `driven` (F x 3Vd) and `driver` (F x 3Vp, or null), sized by the caller.
  virtual void blendBlock(int frameCount, const float* weights, DeviceArray& driven,
                          DeviceArray* driver) {
    blend(frameCount, weights, driven.write<float>(),
          driver != nullptr ? driver->write<float>() : nullptr);
  }
};

/// The host reference implementation (plain C++, no OpenCL).
std::unique_ptr<StageBackend> makeHostStages();

}  // namespace drivenshape
