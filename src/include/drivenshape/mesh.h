// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace drivenshape {

/// V by 3 positions, one vertex per row, float32, row-major so that the memory is the
/// interleaved x0 y0 z0 x1 y1 z1 ... layout that caches, kernels and EXR rows use.
using Positions = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// A polygon mesh as read from OBJ: vertex order exactly as in the file.
///
///   faces:     faceStart[f] .. faceStart[f+1]-1 index into faceVertices (and faceUvs)
///   triangles: fan triangulation of every face, (f, 0, i, i+1) for i in 1..n-2;
///              triangleFace[t] is the face it came from
///   groups:    faceGroup[f] indexes groupNames ("default" when the file names none)
struct Mesh {
  Positions positions;                  ///< V by 3
  std::vector<Eigen::Vector2f> uvs;     ///< texture coordinates (may be empty)
  std::vector<int> faceStart;           ///< F + 1 offsets
  std::vector<int> faceVertices;        ///< vertex ids of all faces, concatenated
  std::vector<int> faceUvs;             ///< uv ids parallel to faceVertices, or empty;
                                        ///< -1 where a corner has none (mixed files)
  std::vector<int> faceGroup;           ///< F group ids
  std::vector<std::string> groupNames;  ///< group id -> name from `g` (or `o`) lines
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> triangles;  ///< T by 3
  std::vector<int> triangleFace;                                     ///< T face ids

  int vertexCount() const { return static_cast<int>(positions.rows()); }
  int faceCount() const { return static_cast<int>(faceGroup.size()); }
  int triangleCount() const { return static_cast<int>(triangles.rows()); }
  bool hasUvs() const { return !faceUvs.empty(); }
  /// Rebuilds `triangles` and `triangleFace` from the faces (fan triangulation).
  void triangulate();
};

/// Checks that the face lists agree with each other and with the vertex and UV counts, which is
/// what triangulate() and every user of a Mesh rely on: faceStart starts at 0, never decreases
/// and ends at faceVertices.size(); every face has at least 3 corners; vertex ids are in
/// [0, V); faceUvs is empty or parallel to faceVertices with ids in [-1, uvs.size()); faceGroup
/// has one valid group id per face; the triangle count fits in an int. Throws Error(kInput)
/// "<source>: ..." naming the first face at fault. Readers call it on everything they load,
/// whatever checksums the file carried.
void validateMesh(const Mesh& mesh, const std::string& source);

/// Hash of what makes two meshes interchangeable for a cache: the vertex count and the face
/// lists (not positions, not UVs). Written into EXR headers and databases.
std::uint64_t topologyHash(const Mesh& mesh);
/// Topology hash of a bare vertex count (for caches read without a mesh).
std::uint64_t topologyHash(int vertexCount);

/// One edge of a mesh: two 0-based vertex ids, the smaller first.
using MeshEdge = std::array<int, 2>;

/// The unique edges of the mesh's faces: the sides of every polygon (each corner with the next,
/// the last with the first), each once however many faces share it, as (a, b) with a < b,
/// sorted. The fan triangulation's diagonals are not edges; a side naming one vertex twice
/// (`f 1 1 2`) is no edge. Linear in the corners, plus a sort.
std::vector<MeshEdge> meshEdges(const Mesh& mesh);

/// The vertices on the mesh's open borders: both ends of every side of meshEdges that exactly
/// one face has (a garment's hems, cuffs and waistband), sorted, each once. A closed mesh has
/// none; a side that two faces share, or more, is not a border. Linear in the corners, plus a
/// sort.
std::vector<int> borderVertices(const Mesh& mesh);

/// |edge| / |rest edge| for every edge of meshEdges with a rest length, in their order: how
/// much each edge of positions `xyz` (3V floats, the mesh's vertex order) is longer than at
/// rest.
std::vector<double> edgeLengthRatios(const Mesh& mesh, const float* xyz);

/// How much larger positions `xyz` are than the mesh's rest positions: the median of
/// edgeLengthRatios; 0 when no edge has a length. About 1 for an animation of the same
/// character in the same units, 100 for one in centimetres against a rest mesh in metres.
double medianEdgeScale(const Mesh& mesh, const float* xyz);

/// Axis-aligned bounds of V by 3 positions; `diagonal` is the length of max - min.
struct Bounds {
  Eigen::Vector3f min = Eigen::Vector3f::Zero();
  Eigen::Vector3f max = Eigen::Vector3f::Zero();
  float diagonal() const { return (max - min).norm(); }
};
Bounds computeBounds(const float* xyz, int vertexCount);
/// The diagonal of `mesh`'s bounding box (its rest positions): the scale tolerances are shares of.
double boundsDiagonal(const Mesh& mesh);

/// Reads a Wavefront OBJ: `v`, `vt`, `f` (any polygon size, v, v/vt, v//vn, v/vt/vn, negative
/// indices), `g`/`o` groups; ignores normals, materials and smoothing. Throws Error(kInput)
/// naming the file and line on malformed content or an out-of-range index.
Mesh readObj(const std::string& path);

/// Writes positions + faces (+ UVs, groups) as OBJ, atomically.
void writeObj(const std::string& path, const Mesh& mesh);

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

}  // namespace drivenshape
