// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstddef>
#include <string>

namespace drivenshape {

/// The world up axis of a scene. drivenshape's own data is Z up and right-handed (Blender's
/// convention; docs/conventions.md): caches, meshes and databases carry no axis of their own,
/// and every writer keeps that axis unless it is asked to convert. Maya and Houdini are Y up.
enum class UpAxis { kY, kZ };

/// "Y" or "Z" (exactly, as USD's upAxis spells them); anything else throws Error(kUsage)
/// naming `what` (the flag, e.g. "--up-axis") and the value.
UpAxis parseUpAxis(const std::string& text, const std::string& what);

/// "Y" or "Z".
const char* upAxisName(UpAxis axis);

/// Rotates `count` points (interleaved x y z, float32: a V by 3 Positions block, or several
/// frames of one) in place from the up axis `from` to `to`, about the X axis:
///
///   Z up -> Y up: (x, y, z) -> (x,  z, -y)    -90 degrees about X
///   Y up -> Z up: (x, y, z) -> (x, -z,  y)    +90 degrees about X (the inverse)
///
/// the convention of Blender's Y-up exporters (forward -Z, up Y), Maya and Houdini. It is a
/// permutation with one sign flip: every value is copied or negated, never rounded, so the
/// result is exact and Z -> Y -> Z gives back the same bits. Nothing changes when from == to.
/// Normals and other directions convert the same way.
void convertUpAxis(float* xyz, std::size_t count, UpAxis from, UpAxis to);

}  // namespace drivenshape
