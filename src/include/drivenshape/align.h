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

/// Vertices of `mesh` named by a selection: the vertices of the faces of each named `g`/`o`
/// group, and/or explicit 0-based vertex indices. `spec` is a comma-separated list whose items
/// are group names or indices / inclusive ranges ("0-99,250"); an empty spec or "all" selects
/// every vertex. Sorted, duplicate-free. `source` names the flag or file in messages. Throws
/// Error(kInput) for an unknown group (listing the known ones), an index out of range or a
/// selection that names no vertex.
std::vector<int> selectVertices(const Mesh& mesh, const std::string& spec,
                                const std::string& source);

/// The vertices of the faces of group `name` of `mesh` (sorted); throws Error(kInput) naming
/// `source` and listing the known groups when the mesh has no such group.
std::vector<int> groupVertices(const Mesh& mesh, const std::string& name,
                               const std::string& source);

/// Lumped vertex areas: a third of the area of every triangle around each vertex (Vp values,
/// scene units squared), on `positions` (V x 3) with `mesh`'s triangles.
std::vector<double> lumpedVertexAreas(const Mesh& mesh, const float* positions);

/// Weighted rigid fit (Kabsch / Umeyama without scale, det(R) = +1) of frames of one mesh to a
/// fixed reference. The weight of a selected vertex is its lumped area on the reference (so a
/// densely meshed region does not dominate; uniform if the selection has no area); other
/// vertices have weight 0.
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

  const std::vector<int>& vertices() const { return mVertices; }

 private:
  std::vector<int> mVertices;
  std::vector<double> mWeights;                         // per selected vertex, sum 1
  Eigen::Matrix<double, Eigen::Dynamic, 3> mReference;  // selected reference points, centred
  Eigen::Vector3d mReferenceCentroid = Eigen::Vector3d::Zero();
};

}  // namespace drivenshape
