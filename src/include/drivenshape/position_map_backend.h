// SPDX-License-Identifier: Apache-2.0
#pragma once

// The position-map kernels' contract that each device implements. The tables they evaluate:
// drivenshape/position_map.h.

#include <cstddef>
#include <memory>
#include <string>

#include <drivenshape/position_map.h>

namespace drivenshape {

/// Evaluates position maps for F frames per call ("osd" side). Two implementations share this
/// contract: OpenCL kernels (makeClPositionMaps) and the plain C++ host reference
/// (makeHostPositionMaps), the oracle in tests. Blocks are frame-major, interleaved xyz:
///
///   frames     F x 3V        frame f, vertex v, axis a at [f * 3V + 3v + a]
///   positions  F x 3(W*H)    frame f, texel i = y * W + x, axis a at [f * 3WH + 3i + a]
///   normals    F x 3(W*H)    same layout; unit length or 0 where the normal is degenerate
///
/// Every texel of every frame is written: active texels get the interpolated value
///   P = p0 + b1 (p1 - p0) + b2 (p2 - p0)
/// (N the same way from the frame's area-weighted vertex normals, then normalised), all other
/// texels 0. upload() once, evaluate() many times. Not thread-safe.
class PositionMapBackend {
 public:
  virtual ~PositionMapBackend() = default;
  /// "host" or the OpenCL device name.
  virtual std::string name() const = 0;
  /// Makes the tables resident (device memory for OpenCL). Must precede evaluate().
  virtual void upload(const PositionMapTables& tables) = 0;
  /// `normals` may be null (no normals computed).
  virtual void evaluate(int frameCount, const float* frames, float* positions, float* normals) = 0;
  /// The largest single buffer the backend can hold, in bytes (bounds the frames per call).
  virtual std::size_t maxBufferBytes() const = 0;
};

/// The host reference implementation (plain C++, no OpenCL).
std::unique_ptr<PositionMapBackend> makeHostPositionMaps();

}  // namespace drivenshape
