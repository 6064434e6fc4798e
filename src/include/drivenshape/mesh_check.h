// SPDX-License-Identifier: Apache-2.0
#pragma once

// Is a driver mesh a surface the inside audit and the penetration resolution can trust? Both
// take the sign of the distance to the driver from its angle-weighted pseudo-normals, which
// tell inside from outside only on a closed, manifold, consistently oriented surface: a hole,
// a fin face or a flipped face turns cloth outside the body into "inside" cloth that the
// resolution then pushes the wrong way, and a degenerate face has no normal at all. The cloth
// (driven) mesh is open by nature and is never checked this way.

#include <string>
#include <vector>

#include <drivenshape/mesh.h>

namespace drivenshape {

/// One edge as the file names it: 0-based vertex ids in the order the face `face` traverses it
/// (print them + 1 for the OBJ's 1-based numbers).
struct MeshEdgeRef {
  int from = -1;
  int to = -1;
  int face = -1;       ///< 0-based face (the order of the file's `f` lines)
  int otherFace = -1;  ///< misoriented edges: the second face traversing it the same way
  int uses = 0;        ///< faces that use the edge
};

/// What countMeshDefects found. Edges are unordered vertex pairs of consecutive corners of the
/// faces without a repeated vertex (a face that repeats a vertex is not a polygon and adds no
/// edge); every count is 0 for a closed, manifold, consistently oriented mesh. The `first*`
/// fields are the first culprit of each kind in face order (faces as in the file, each face's
/// edges from its first corner), empty or -1 when there is none.
struct MeshDefects {
  int faces = 0;
  /// Faces that repeat a vertex (`f 1 1 2`) or whose (vector) area is zero next to the square
  /// of their longest edge (collinear or coincident corners): they have no normal.
  int degenerateFaces = 0;
  /// Edges used by exactly one face: the border of a hole or of an open mesh.
  int openEdges = 0;
  /// Edges used by more than two faces (a fin face on an existing edge).
  int nonManifoldEdges = 0;
  /// Edges of two faces that traverse them in the same direction: one of the faces is flipped
  /// against the other.
  int misorientedEdges = 0;
  int firstDegenerateFace = -1;             ///< 0-based face
  std::vector<int> firstDegenerateCorners;  ///< its 0-based vertex ids
  MeshEdgeRef firstOpenEdge;
  MeshEdgeRef firstNonManifoldEdge;
  MeshEdgeRef firstMisorientedEdge;

  /// A closed, manifold, consistently oriented mesh with at least one face and no degenerate
  /// one: what the inside audit and the resolution assume.
  bool trusted() const {
    return faces > 0 && degenerateFaces == 0 && openEdges == 0 && nonManifoldEdges == 0 &&
           misorientedEdges == 0;
  }
  /// At least one face with an area: something to bind cloth to.
  bool bindable() const { return degenerateFaces < faces; }
  /// The counts that are not zero, each with its first culprit in the OBJ's 1-based vertex and
  /// face numbers, e.g. "3 open edges (used by one face; the first: vertices 12-40 of face 7)";
  /// "no defects" when trusted().
  std::string describe() const;
};

/// Counts the degenerate faces, open, non-manifold and misoriented edges of `mesh` (a mesh
/// validateMesh accepts). Linear in the corners (one hash map of the edges).
MeshDefects countMeshDefects(const Mesh& mesh);

/// Which command a driver mesh goes into, for what checkDriverMesh's messages say happens.
enum class DriverMeshUse {
  kDatabase,  ///< `db build`: the database's rest driver
  kBake,      ///< `bake`: the database's driver mesh
  kEval       ///< `eval`: the driver of the penetration figures and the baseline
};

/// Checks a driver mesh where it enters a command. A trusted mesh (MeshDefects::trusted)
/// returns "". Otherwise this throws Error(kInput) "<source>: ..." naming the counts, the first
/// culprit of each kind (OBJ numbers), why it matters and what to do, unless `allowUntrusted`
/// (`--untrusted-driver`) and the mesh has a face to bind to: it then returns the warning to
/// print, which says what the command leaves out for it (the inside audit and the penetration
/// resolution; eval's penetration figures). A mesh with no face, or none that is not
/// degenerate, is refused whatever `allowUntrusted` says.
std::string checkDriverMesh(const Mesh& mesh, const std::string& source, DriverMeshUse use,
                            bool allowUntrusted);

}  // namespace drivenshape
