// SPDX-License-Identifier: Apache-2.0
#include "local_encoding.h"

#include <Eigen/Core>
#include <cstddef>

#include <drivenshape/error.h>

#include "candidates.h"
#include "triangle_distance.h"

namespace drivenshape {

void encodeLocal(const Mesh& driver, const float* pose, int count, const float* points,
                 const SurfaceHit* hits, float* local) {
  if (count < 0) {
    DS_THROW(kInternal, "encodeLocal: negative point count ", count);
  }
  if (count > 0 && (pose == nullptr || points == nullptr || hits == nullptr || local == nullptr)) {
    DS_THROW(kInternal, "encodeLocal: called with a null buffer");
  }
  const int vertexCount = driver.vertexCount();
  correction::checkFinite("local-frame encoding", "driver vertex", 1, vertexCount, pose);
  correction::checkFinite("local-frame encoding", "driven point", 1, count, points);
  correction::checkHits("local-frame encoding", driver.triangleCount(),
                        static_cast<std::size_t>(count), count > 0 ? count : 1, hits);
  for (int i = 0; i < count; ++i) {
    const SurfaceHit& hit = hits[i];
    int corner[3];
    for (int k = 0; k < 3; ++k) {
      corner[k] = driver.triangles(hit.triangle, k);
      if (corner[k] < 0 || corner[k] >= vertexCount) {
        DS_THROW(kInput, "local-frame encoding: driver triangle ", hit.triangle, " names vertex ",
                 corner[k], " but the driver has ", vertexCount, " vertices");
      }
    }
    correction::LocalFrame frame;
    const bool ok = correction::localFrame(
        correction::loadPoint(pose, corner[0]), correction::loadPoint(pose, corner[1]),
        correction::loadPoint(pose, corner[2]), hit.u, hit.v, frame);
    const Eigen::Vector3d d = correction::loadPoint(points, i) - frame.q;
    const Eigen::Vector3d l =
        ok ? Eigen::Vector3d(d.dot(frame.e1), d.dot(frame.e2), d.dot(frame.n)) : d;
    for (int k = 0; k < 3; ++k) {
      local[3 * static_cast<std::size_t>(i) + static_cast<std::size_t>(k)] =
          static_cast<float>(l[k]);
    }
  }
}

}  // namespace drivenshape
