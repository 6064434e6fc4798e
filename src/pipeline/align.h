// SPDX-License-Identifier: Apache-2.0
#pragma once

// Rigid alignment of shot driver frames to the database's reference frame (issue 4, step 1):
// the weights compare positions, so a character that walks through the set must first be
// brought back to where the database was built. The reference is the database's rest driver
// (the driver OBJ); every shot frame and every database shape is fitted to it.

#include <Eigen/Core>
#include <string>
#include <vector>

#include <drivenshape/mesh.h>

namespace drivenshape {

/// A rigid motion x -> rotation * x + translation (proper rotation, no scale), in double.
struct RigidTransform {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  /// out = rotation * in + translation for `count` points (count x 3, interleaved). `out` may
  /// alias `in`.
  void apply(const float* in, int count, float* out) const;
  /// The inverse motion: out = rotation^T (in - translation). `out` may alias `in`.
  void applyInverse(const float* in, int count, float* out) const;
};

/// Lumped vertex areas: a third of the area of every triangle around each vertex (Vp values,
/// scene units squared), on `positions` (V x 3) with `mesh`'s triangles.
std::vector<double> lumpedVertexAreas(const Mesh& mesh, const float* positions);

/// Settings of RigidAligner::weightByRigidity. The defaults were chosen on the reference
/// scenes (docs/method.md, "Accuracy"); lengths are fractions of the bounding-box diagonal of the
/// selected rest vertices, so they hold in any scene unit.
struct RigidityOptions {
  /// Residual scale tau of the robust weights area / (r^2 + tau^2): vertices that move more
  /// than about tau away from the common rigid motion count as articulating.
  double residualScale = 0.01;
  /// Radius of the seed patches (balls at rest around every (n / seedCount)-th selected vertex).
  double seedRadius = 0.1;
  /// Number of seed patches tried (plus the whole selection).
  int seedCount = 64;
  /// Reweighting passes after the best seed.
  int iterations = 3;
  /// Host threads for the fits over the examples (0 = one per hardware thread). The weights do
  /// not depend on it: every sum runs in the same order.
  int threads = 0;
};

/// Weighted rigid fit (Kabsch / Umeyama without scale, det(R) = +1) of frames of one mesh to a
/// fixed reference. The weight of a selected vertex is its lumped area on the reference (so a
/// densely meshed region does not dominate; uniform if the selection has no area), or, after
/// weightByRigidity, that area times how rigidly the vertex moves across example frames;
/// other vertices have weight 0.
class RigidAligner {
 public:
  /// `reference` is V x 3 (the rest driver). Throws Error(kInput) naming `source` when the
  /// selection has fewer than 3 vertices or its weighted reference points are (nearly)
  /// collinear: a rigid fit would then leave a rotation free.
  RigidAligner(const Mesh& mesh, const float* reference, std::vector<int> vertices,
               const std::string& source);

  /// The rigid motion that best maps `frame` (V x 3) onto the reference:
  ///   argmin_{R, t} sum_v w_v |R x_v + t - r_v|^2.
  RigidTransform fit(const float* frame) const;

  /// Reweights the selection so that the fit locks onto the part of the mesh that moves
  /// rigidly across `exampleCount` example frames (`examples`: exampleCount x V x 3 with V the
  /// mesh's vertex count, e.g. the database's driver shapes) and ignores the articulating
  /// rest (legs under a pelvis, a forearm under an upper arm). With r_v^2 the mean over the
  /// examples of the squared residual |R_e x_v + t_e - r_v|^2 of each example's fit under given
  /// weights:
  ///  1. seeds: the whole selection and `seedCount` balls of radius `seedRadius` around
  ///     every (n / seedCount)-th selected vertex, each fitted with area weights; the seed whose
  ///     fits leave the most area within tau, sum_v area_v tau^2 / (r_v^2 + tau^2), wins (the first
  ///     on a tie);
  ///  2. w_v = area_v / (r_v^2 + tau^2) from the best seed's residuals, then `iterations`
  ///     passes of refitting every example with w and recomputing w from the new residuals.
  /// Deterministic (fixed order, no randomness). Without examples the weights stay the
  /// areas. Throws Error(kInput) naming the source when the resulting weights are collinear.
  void weightByRigidity(const float* examples, int exampleCount,
                        const RigidityOptions& options = RigidityOptions());

  const std::vector<int>& vertices() const { return mVertices; }
  /// Per selected vertex (same order as vertices()), summing to 1.
  const std::vector<double>& weights() const { return mWeights; }

 private:
  void setWeights(std::vector<double> weights);
  RigidTransform fitWith(const std::vector<double>& weights, const float* frame) const;

  std::string mSource;
  int mVertexCount = 0;  // of the mesh: the stride of frames and examples
  std::vector<int> mVertices;
  std::vector<double> mAreas;                           // per selected vertex, sum 1
  std::vector<double> mWeights;                         // per selected vertex, sum 1
  Eigen::Matrix<double, Eigen::Dynamic, 3> mReference;  // selected reference points, centred
  Eigen::Vector3d mReferenceCentroid = Eigen::Vector3d::Zero();
};

}  // namespace drivenshape
