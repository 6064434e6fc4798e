// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/mesh_check.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <unordered_map>
#include <vector>

#include <drivenshape/error.h>

namespace drivenshape {
namespace {

/// A face whose vector area is at most this times the square of its longest edge has no usable
/// normal: float corners that are collinear up to rounding stay below about the float epsilon
/// (6e-8) near the origin, the sample drivers' thinnest faces give more than 5e-2.
constexpr double kZeroAreaRatio = 1e-7;

/// How the faces use one unordered edge.
struct EdgeUse {
  int uses = 0;
  int forward = 0;  ///< traversals from the smaller vertex id to the larger
  int face = -1;    ///< the first two faces that use it
  int secondFace = -1;
};

std::uint64_t edgeKey(int a, int b) {
  const auto lo = static_cast<std::uint32_t>(std::min(a, b));
  const auto hi = static_cast<std::uint32_t>(std::max(a, b));
  return (static_cast<std::uint64_t>(lo) << 32) | hi;
}

/// Whether corners [begin, end) name a vertex twice: pairwise for the usual small faces, by
/// sorting for long polygons (so a hostile OBJ face of a million corners stays n log n).
bool repeatsVertex(const Mesh& mesh, int begin, int end, std::vector<int>& scratch) {
  const auto corner = [&](int c) { return mesh.faceVertices[static_cast<std::size_t>(c)]; };
  if (end - begin > 16) {
    scratch.assign(mesh.faceVertices.begin() + begin, mesh.faceVertices.begin() + end);
    std::sort(scratch.begin(), scratch.end());
    return std::adjacent_find(scratch.begin(), scratch.end()) != scratch.end();
  }
  for (int i = begin; i < end; ++i) {
    for (int j = i + 1; j < end; ++j) {
      if (corner(i) == corner(j)) {
        return true;
      }
    }
  }
  return false;
}

/// Whether the face's vector area vanishes next to its longest edge (or is not a number).
bool hasNoArea(const Mesh& mesh, int begin, int end) {
  const auto corner = [&](int c) -> Eigen::Vector3d {
    return mesh.positions.row(mesh.faceVertices[static_cast<std::size_t>(c)])
        .transpose()
        .cast<double>();
  };
  const Eigen::Vector3d origin = corner(begin);
  Eigen::Vector3d area = Eigen::Vector3d::Zero();
  double longest = 0.0;
  for (int c = begin; c < end; ++c) {
    const Eigen::Vector3d a = corner(c);
    const Eigen::Vector3d b = corner(c + 1 < end ? c + 1 : begin);
    longest = std::max(longest, (b - a).squaredNorm());
    area += (a - origin).cross(b - origin);
  }
  return !(0.5 * area.norm() > kZeroAreaRatio * longest);
}

std::string plural(int count, const char* noun) {
  std::ostringstream out;
  out << count << " " << noun << (count == 1 ? "" : "s");
  return out.str();
}

std::string edgeText(const MeshEdgeRef& edge) {
  std::ostringstream out;
  out << "vertices " << edge.from + 1 << "-" << edge.to + 1;
  return out.str();
}

}  // namespace

std::string MeshDefects::describe() const {
  std::ostringstream out;
  const char* separator = "";
  if (faces == 0) {
    return "no faces";
  }
  if (degenerateFaces > 0) {
    out << plural(degenerateFaces, "degenerate face")
        << " (a repeated vertex or no area; the first: face " << firstDegenerateFace + 1
        << ", vertices";
    constexpr std::size_t kShown = 8;  // of a long polygon
    for (std::size_t c = 0; c < std::min(kShown, firstDegenerateCorners.size()); ++c) {
      out << " " << firstDegenerateCorners[c] + 1;
    }
    if (firstDegenerateCorners.size() > kShown) {
      out << " ... (" << firstDegenerateCorners.size() << " corners)";
    }
    out << ")";
    separator = "; ";
  }
  if (openEdges > 0) {
    out << separator << plural(openEdges, "open edge")
        << " (used by one face; the first: " << edgeText(firstOpenEdge) << " of face "
        << firstOpenEdge.face + 1 << ")";
    separator = "; ";
  }
  if (nonManifoldEdges > 0) {
    out << separator << plural(nonManifoldEdges, "non-manifold edge")
        << " (used by more than two faces; the first: " << edgeText(firstNonManifoldEdge)
        << ", used by " << firstNonManifoldEdge.uses << " faces, face "
        << firstNonManifoldEdge.face + 1 << " first)";
    separator = "; ";
  }
  if (misorientedEdges > 0) {
    out << separator << plural(misorientedEdges, "misoriented edge")
        << " (two faces traverse each the same way, so one of them is flipped; the first: "
        << edgeText(firstMisorientedEdge) << " in faces " << firstMisorientedEdge.face + 1
        << " and " << firstMisorientedEdge.otherFace + 1 << ")";
    separator = "; ";
  }
  return *separator == '\0' ? std::string("no defects") : out.str();
}

MeshDefects countMeshDefects(const Mesh& mesh) {
  MeshDefects result;
  result.faces = mesh.faceStart.empty() ? 0 : static_cast<int>(mesh.faceStart.size()) - 1;
  std::vector<char> proper(static_cast<std::size_t>(result.faces), 0);
  std::unordered_map<std::uint64_t, EdgeUse> edges;
  edges.reserve(mesh.faceVertices.size());
  std::vector<int> scratch;
  for (int f = 0; f < result.faces; ++f) {
    const int begin = mesh.faceStart[f];
    const int end = mesh.faceStart[f + 1];
    const bool repeats = repeatsVertex(mesh, begin, end, scratch);
    if (repeats || hasNoArea(mesh, begin, end)) {
      if (result.degenerateFaces++ == 0) {
        result.firstDegenerateFace = f;
        result.firstDegenerateCorners.assign(mesh.faceVertices.begin() + begin,
                                             mesh.faceVertices.begin() + end);
      }
    }
    if (repeats) {
      continue;  // not a polygon: it adds no edge
    }
    proper[static_cast<std::size_t>(f)] = 1;
    for (int c = begin; c < end; ++c) {
      const int a = mesh.faceVertices[static_cast<std::size_t>(c)];
      const int b = mesh.faceVertices[static_cast<std::size_t>(c + 1 < end ? c + 1 : begin)];
      EdgeUse& use = edges[edgeKey(a, b)];
      ++use.uses;
      use.forward += a < b ? 1 : 0;
      if (use.face < 0) {
        use.face = f;
      } else if (use.secondFace < 0) {
        use.secondFace = f;
      }
    }
  }
  for (const auto& entry : edges) {
    const EdgeUse& use = entry.second;
    result.openEdges += use.uses == 1 ? 1 : 0;
    result.nonManifoldEdges += use.uses > 2 ? 1 : 0;
    result.misorientedEdges += use.uses == 2 && use.forward != 1 ? 1 : 0;
  }
  // The first culprit of each kind, in face order.
  for (int f = 0; f < result.faces; ++f) {
    if (proper[static_cast<std::size_t>(f)] == 0) {
      continue;
    }
    const int begin = mesh.faceStart[f];
    const int end = mesh.faceStart[f + 1];
    for (int c = begin; c < end; ++c) {
      const int a = mesh.faceVertices[static_cast<std::size_t>(c)];
      const int b = mesh.faceVertices[static_cast<std::size_t>(c + 1 < end ? c + 1 : begin)];
      const EdgeUse& use = edges.at(edgeKey(a, b));
      MeshEdgeRef* first = use.uses == 1                       ? &result.firstOpenEdge
                           : use.uses > 2                      ? &result.firstNonManifoldEdge
                           : use.uses == 2 && use.forward != 1 ? &result.firstMisorientedEdge
                                                               : nullptr;
      if (first != nullptr && first->face < 0) {
        *first = {a, b, f, use.uses == 2 ? use.secondFace : -1, use.uses};
      }
    }
  }
  return result;
}

std::string checkDriverMesh(const Mesh& mesh, const std::string& source, DriverMeshUse use,
                            bool allowUntrusted) {
  const MeshDefects defects = countMeshDefects(mesh);
  if (defects.trusted()) {
    return {};
  }
  if (!defects.bindable()) {
    DS_THROW(kInput, source, ": ",
             defects.faces == 0
                 ? std::string("the driver mesh has no faces")
                 : "every face of the driver mesh is degenerate: " + defects.describe(),
             ". There is nothing to bind the cloth to, even with --untrusted-driver: pass the "
             "driver's rest mesh with its faces");
  }
  const char* repair = use == DriverMeshUse::kBake
                           ? "rebuild the database from a repaired driver mesh"
                           : "repair the mesh";
  const char* without =
      use == DriverMeshUse::kDatabase
          ? "build the database anyway (its bakes then need --untrusted-driver as well and run "
            "without the inside audit and the penetration resolution)"
      : use == DriverMeshUse::kBake ? "bake without the inside audit and the penetration resolution"
                                    : "evaluate without the penetration figures";
  if (!allowUntrusted) {
    DS_THROW(kInput, source, ": the driver mesh is not a closed, consistently oriented surface: ",
             defects.describe(),
             ". The inside test of the bake's audit and penetration resolution (and of eval's "
             "penetration figures) assumes one and would count and push cloth the wrong way: ",
             repair,
             " (fill the holes, delete the degenerate and fin faces, make the face orientation "
             "consistent), or pass --untrusted-driver to ",
             without);
  }
  const char* consequence =
      use == DriverMeshUse::kDatabase
          ? "building the database anyway; every bake of it needs --untrusted-driver and runs "
            "without the inside audit and the penetration resolution"
      : use == DriverMeshUse::kBake
          ? "baking without the inside audit and the penetration resolution (the report's "
            "settings say untrusted_driver: true)"
          : "the penetration figures (inside counts and depths) are left out";
  return source +
         ": the driver mesh is not a closed, consistently oriented surface: " + defects.describe() +
         "; --untrusted-driver: " + consequence;
}

}  // namespace drivenshape
