// SPDX-License-Identifier: Apache-2.0
#pragma once

// Local coordinates of points bound to a driver surface: once per database (its shapes, the
// pose model's basis) on the host, in double. ClosestBackend::rebuild (src/devices/closest.h)
// is the inverse, run per frame on the device.

#include <drivenshape/binding.h>
#include <drivenshape/mesh.h>

namespace drivenshape {

/// Host-side encoding for local-frame blending (the inverse of ClosestBackend::rebuild, in
/// double arithmetic): the local coordinates of `count` points (count x 3) with their hits on
/// one pose (Vp x 3) of `driver`'s topology, written to local (count x 3).
void encodeLocal(const Mesh& driver, const float* pose, int count, const float* points,
                 const SurfaceHit* hits, float* local);

}  // namespace drivenshape
