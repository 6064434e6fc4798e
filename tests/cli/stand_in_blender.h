// SPDX-License-Identifier: Apache-2.0
#pragma once

// What the stand-in Blender of test_simulate_command adds to the bake's positions, shared by
// the stand-in (which writes it) and the test (which builds the windows it expects from it).

namespace drivenshape::testing {

/// The stand-in's "simulation" of frame `frame`: the bake moved by a different amount per frame,
/// vertex and axis (so that a frame or vertex taken from the wrong place shows).
inline float simulatedOffset(int frame, int vertex, int axis) {
  return 0.25f + 0.01f * static_cast<float>(frame) + 0.001f * static_cast<float>(vertex) -
         0.1f * static_cast<float>(axis);
}

}  // namespace drivenshape::testing
