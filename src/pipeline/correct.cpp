// SPDX-License-Identifier: Apache-2.0
// The correction of a chunk as one call: closest triangles on the blended driver, then the
// local-frame transfer of the blended cloth onto the shot's driver.

#include "closest.h"

namespace drivenshape {

void correct(ClosestBackend& backend, int frameCount, const float* blendedDriver,
             const float* blendedDriven, const float* shotDriver, float* corrected,
             SurfaceHit* hits) {
  backend.closest(frameCount, blendedDriver, blendedDriven, hits);
  backend.transfer(frameCount, hits, blendedDriver, shotDriver, blendedDriven, corrected);
}

}  // namespace drivenshape
