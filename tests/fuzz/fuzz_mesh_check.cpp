// SPDX-License-Identifier: Apache-2.0
// Driver mesh check (src/io/mesh_check.cpp): readObj on the input, then countMeshDefects against
// a brute-force count of the edges (an ordered map of every face's edges), the same edge
// counts with every face flipped, and checkDriverMesh's contract for every command and override:
// a trusted mesh passes silently, an untrusted one is Error(kInput) naming the file or (allowed,
// with a face to bind to) a warning naming it, one with nothing to bind to is always refused.

#include <algorithm>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <drivenshape/mesh.h>
#include <drivenshape/mesh_check.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

namespace {

constexpr const char* kReader = "countMeshDefects";

struct Traversal {
  int face;
  bool forward;  // from the smaller vertex id to the larger
};

bool hasRepeat(std::vector<int> corners) {
  std::sort(corners.begin(), corners.end());
  return std::adjacent_find(corners.begin(), corners.end()) != corners.end();
}

std::vector<int> faceCorners(const ds::Mesh& mesh, int f) {
  return {mesh.faceVertices.begin() + mesh.faceStart[f],
          mesh.faceVertices.begin() + mesh.faceStart[f + 1]};
}

/// The first culprit the check must name for `kind`, from the brute-force edge table.
ds::MeshEdgeRef firstEdge(const ds::Mesh& mesh,
                          const std::map<std::pair<int, int>, std::vector<Traversal>>& edges,
                          bool (*kind)(const std::vector<Traversal>&)) {
  for (int f = 0; f < mesh.faceCount(); ++f) {
    const std::vector<int> corners = faceCorners(mesh, f);
    if (hasRepeat(corners)) {
      continue;
    }
    for (std::size_t c = 0; c < corners.size(); ++c) {
      const int a = corners[c];
      const int b = corners[(c + 1) % corners.size()];
      const std::vector<Traversal>& uses = edges.at({std::min(a, b), std::max(a, b)});
      if (kind(uses)) {
        const int other = uses.size() == 2 ? uses[1].face : -1;
        return {a, b, f, other, static_cast<int>(uses.size())};
      }
    }
  }
  return {};
}

bool isOpen(const std::vector<Traversal>& uses) {
  return uses.size() == 1;
}
bool isNonManifold(const std::vector<Traversal>& uses) {
  return uses.size() > 2;
}
bool isMisoriented(const std::vector<Traversal>& uses) {
  return uses.size() == 2 && uses[0].forward == uses[1].forward;
}

bool sameEdge(const ds::MeshEdgeRef& a, const ds::MeshEdgeRef& b) {
  return a.from == b.from && a.to == b.to && a.face == b.face && a.otherFace == b.otherFace &&
         (a.face < 0 || a.uses == b.uses);
}

/// countMeshDefects against the brute-force edge table and the repeated-vertex faces.
void checkCounts(const ds::Mesh& mesh, const ds::MeshDefects& d) {
  std::map<std::pair<int, int>, std::vector<Traversal>> edges;
  int repeated = 0;
  for (int f = 0; f < mesh.faceCount(); ++f) {
    const std::vector<int> corners = faceCorners(mesh, f);
    if (hasRepeat(corners)) {
      ++repeated;
      continue;
    }
    for (std::size_t c = 0; c < corners.size(); ++c) {
      const int a = corners[c];
      const int b = corners[(c + 1) % corners.size()];
      edges[{std::min(a, b), std::max(a, b)}].push_back({f, a < b});
    }
  }
  int open = 0, nonManifold = 0, misoriented = 0;
  for (const auto& entry : edges) {
    open += isOpen(entry.second) ? 1 : 0;
    nonManifold += isNonManifold(entry.second) ? 1 : 0;
    misoriented += isMisoriented(entry.second) ? 1 : 0;
  }
  ds::fuzz::require(d.faces == mesh.faceCount(), kReader, "the face count is not the mesh's");
  ds::fuzz::require(
      d.openEdges == open && d.nonManifoldEdges == nonManifold && d.misorientedEdges == misoriented,
      kReader, "an edge count differs from the brute-force count");
  // Zero area is the check's own test; a repeated vertex always makes a face degenerate.
  ds::fuzz::require(d.degenerateFaces >= repeated && d.degenerateFaces <= d.faces, kReader,
                    "the degenerate face count is out of range");
  ds::fuzz::require((d.degenerateFaces == 0) == (d.firstDegenerateFace < 0) &&
                        (d.firstDegenerateFace < 0 ||
                         (d.firstDegenerateFace < d.faces &&
                          d.firstDegenerateCorners == faceCorners(mesh, d.firstDegenerateFace))),
                    kReader, "the first degenerate face is not one of the mesh's faces");
  ds::fuzz::require(sameEdge(d.firstOpenEdge, firstEdge(mesh, edges, isOpen)) &&
                        sameEdge(d.firstNonManifoldEdge, firstEdge(mesh, edges, isNonManifold)) &&
                        sameEdge(d.firstMisorientedEdge, firstEdge(mesh, edges, isMisoriented)),
                    kReader, "a first culprit is not the first in face order");
  ds::fuzz::require(d.trusted() == (d.faces > 0 && d.degenerateFaces == 0 && open == 0 &&
                                    nonManifold == 0 && misoriented == 0),
                    kReader, "trusted() disagrees with the counts");
  ds::fuzz::require(!d.describe().empty(), kReader, "describe() is empty");
}

/// What checkDriverMesh did: the warning it returned, or the Error it threw.
struct Outcome {
  std::optional<std::string> warning;
  std::optional<ds::Error> error;
};

Outcome runCheck(const ds::Mesh& mesh, ds::DriverMeshUse use, bool allow) {
  Outcome outcome;
  try {
    outcome.warning = ds::checkDriverMesh(mesh, "input.obj", use, allow);
  } catch (const ds::Error& e) {
    outcome.error = e;
  } catch (const std::exception& e) {
    ds::fuzz::reportFinding("checkDriverMesh", typeid(e).name(), e.what());
  }
  return outcome;
}

void checkPolicy(const ds::Mesh& mesh, const ds::MeshDefects& d) {
  for (const ds::DriverMeshUse use :
       {ds::DriverMeshUse::kDatabase, ds::DriverMeshUse::kBake, ds::DriverMeshUse::kEval}) {
    for (const bool allow : {false, true}) {
      const Outcome o = runCheck(mesh, use, allow);
      const bool passes = d.trusted() || (allow && d.bindable());
      ds::fuzz::require(passes == o.warning.has_value(), "checkDriverMesh",
                        "refused a mesh it should pass, or passed one it should refuse");
      if (o.error) {
        ds::fuzz::require(o.error->code() == ds::ErrorCode::kInput &&
                              std::string(o.error->what()).rfind("input.obj: ", 0) == 0,
                          "checkDriverMesh", "a refusal is not an input error naming the file");
      } else {
        ds::fuzz::require(o.warning->empty() == d.trusted() &&
                              (o.warning->empty() || o.warning->rfind("input.obj: ", 0) == 0),
                          "checkDriverMesh",
                          "the warning is missing, unexpected or does not name the file");
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ds::fuzz::writeInput("input.obj", data, size);
  ds::Mesh mesh;
  if (!ds::fuzz::expectOnlyErrors("readObj", [&] { mesh = ds::readObj(path); })) {
    return 0;
  }
  ds::MeshDefects defects;
  ds::fuzz::expectSuccess(kReader, [&] { defects = ds::countMeshDefects(mesh); });
  checkCounts(mesh, defects);
  checkPolicy(mesh, defects);

  // Flipping every face flips every traversal: the same edge counts. (Not the degenerate faces:
  // summed in another order, an area right at the zero-area threshold may land either side.)
  ds::Mesh flipped = mesh;
  for (int f = 0; f < flipped.faceCount(); ++f) {
    std::reverse(flipped.faceVertices.begin() + flipped.faceStart[f],
                 flipped.faceVertices.begin() + flipped.faceStart[f + 1]);
  }
  ds::MeshDefects flippedDefects;
  ds::fuzz::expectSuccess(kReader, [&] { flippedDefects = ds::countMeshDefects(flipped); });
  ds::fuzz::require(flippedDefects.openEdges == defects.openEdges &&
                        flippedDefects.nonManifoldEdges == defects.nonManifoldEdges &&
                        flippedDefects.misorientedEdges == defects.misorientedEdges,
                    kReader, "flipping every face changed the counts");
  return 0;
}
