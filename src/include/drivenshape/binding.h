// SPDX-License-Identifier: Apache-2.0
#pragma once

// How the cloth is bound to the driver's surface (docs/method.md, "Local frames, resolution,
// layers"): a driven point's closest point on a driver triangle (SurfaceHit), the binding masks
// that restrict which driver triangles a driven vertex may bind to, and the side of the skin each
// driven point lives on. The backends that find and use these hits are private to the library
// (src/devices/closest.h).

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/mesh.h>

namespace drivenshape {

/// The closest point of a driver triangle to a point:
///   q = a + u (b - a) + v (c - a),  (a, b, c) = the vertices of mesh.triangles row `triangle`,
/// with u >= 0, v >= 0, u + v <= 1, at squared distance `distance2` (squared scene units).
/// Bit-compatible with DsSurfaceHit in kernels/correction_types.h.
struct SurfaceHit {
  std::int32_t triangle = -1;
  float u = 0.0f;
  float v = 0.0f;
  float distance2 = 0.0f;
};

/// Which driver triangles each driven vertex may bind to.
///
///   vertexClass    Vd ints: -1 = any triangle, else an index into the classes
///   classTriangles C sorted, duplicate-free, non-empty lists of driver triangle ids
///
/// Vertices that share a class share the allowed set, so the candidate search builds one tree
/// per class.
class BindingMask {
 public:
  /// Every vertex of a driven mesh with `drivenVertexCount` vertices binds to every triangle.
  static BindingMask all(int drivenVertexCount);

  /// A mask from its tables. Throws Error(kInput) on a class index out of range or an empty
  /// class; sorts the class lists and drops duplicates.
  BindingMask(std::vector<int> vertexClass, std::vector<std::vector<int>> classTriangles);

  int drivenVertexCount() const { return static_cast<int>(mVertexClass.size()); }
  int classCount() const { return static_cast<int>(mClassTriangles.size()); }
  /// -1 (any triangle) or the class of driven vertex `vertex`.
  int vertexClass(int vertex) const { return mVertexClass[vertex]; }
  const std::vector<int>& vertexClasses() const { return mVertexClass; }
  /// The sorted driver triangle ids of class `c`.
  const std::vector<int>& classTriangles(int c) const { return mClassTriangles[c]; }
  /// Whether driven vertex `vertex` may bind to driver triangle `triangle`.
  bool allows(int vertex, int triangle) const;
  /// True when no vertex is restricted.
  bool isAll() const;

 private:
  std::vector<int> mVertexClass;
  std::vector<std::vector<int>> mClassTriangles;
};

/// Reads a binding-mask file (JSON). The format:
///
///   {
///     "version": 1,                                  (optional; 1 is the only version)
///     "bindings": [
///       {"driven": "left_leg", "driver": ["left_leg", "pelvis"]},
///       {"name": "cuff",                             (optional label for messages)
///        "driven": {"groups": ["cuff"], "vertices": [0, 1, "5-9"]},
///        "driver": {"faces": [12, "40-47"]}}
///     ]
///   }
///
/// "driven" names driven-mesh vertices: a group name, a list of group names, or an object with
/// "groups" (names) and/or "vertices" (indices). A group is the set of vertices of the faces of
/// that `g` (or `o`) group of the driven OBJ. "driver" names driver faces: a group name, a list
/// of names, or an object with "groups" and/or "faces" (OBJ face indices); a face stands for
/// all of its fan triangles (Mesh::triangleFace). Indices are 0-based, in file order; a string
/// "a-b" is the inclusive range a..b. Keys "comment" (anywhere) are ignored; other keys are
/// errors. Vertices named in no entry bind to every driver triangle.
///
/// Throws Error(kInput) naming the file and the entry ("bindings[2]") for: a file that cannot
/// be read, malformed JSON, an unknown key, an unknown group (the message lists the known
/// names), a group or list that names nothing, an index out of range, a bad range, and a
/// driven vertex named by two entries.
BindingMask readBindingMask(const std::string& path, const Mesh& driver, const Mesh& driven);

/// The same from JSON text; `source` names the text in messages (a file path, "--bind").
BindingMask parseBindingMask(const std::string& jsonText, const std::string& source,
                             const Mesh& driver, const Mesh& driven);

/// The side of the driver's skin a driven point lives on (ClosestBackend::setSides): cloth over
/// the body lives outside, a muscle or fat layer under the skin inside.
inline constexpr std::int8_t kSideOutside = 1;
inline constexpr std::int8_t kSideInside = -1;

}  // namespace drivenshape
