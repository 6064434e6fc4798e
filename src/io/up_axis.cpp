// SPDX-License-Identifier: Apache-2.0
#include "up_axis.h"

#include <drivenshape/error.h>

namespace drivenshape {

UpAxis parseUpAxis(const std::string& text, const std::string& what) {
  if (text == "Y") {
    return UpAxis::kY;
  }
  if (text == "Z") {
    return UpAxis::kZ;
  }
  DS_THROW(kUsage, what, " '", text,
           "': use Z (drivenshape's axis, the default: points unchanged) or Y (points rotated "
           "to Y up for Maya, Houdini or a Y-up import)");
}

const char* upAxisName(UpAxis axis) {
  return axis == UpAxis::kY ? "Y" : "Z";
}

void convertUpAxis(float* xyz, std::size_t count, UpAxis from, UpAxis to) {
  if (from == to) {
    return;
  }
  // Unary minus only flips the sign bit: no rounding, so the conversion is exact both ways.
  const bool toY = to == UpAxis::kY;
  for (std::size_t i = 0; i < count; ++i) {
    float* p = xyz + 3 * i;
    const float y = p[1];
    const float z = p[2];
    p[1] = toY ? z : -z;
    p[2] = toY ? -y : y;
  }
}

}  // namespace drivenshape
