// SPDX-License-Identifier: Apache-2.0
// Vertices of a mesh named by a selection: OBJ groups and index ranges (the binding and align
// groups, regions).
#include <drivenshape/mesh.h>

#include <algorithm>
#include <cctype>
#include <exception>
#include <string>
#include <vector>

#include <drivenshape/error.h>

#include "text.h"

namespace drivenshape {
namespace {

std::string knownGroups(const Mesh& mesh) {
  std::string names;
  for (const std::string& name : mesh.groupNames) {
    names += (names.empty() ? "" : ", ") + name;
  }
  return names.empty() ? std::string("none") : names;
}

bool isIndexItem(const std::string& item) {
  return !item.empty() && std::all_of(item.begin(), item.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c)) || c == '-';
  }) && std::isdigit(static_cast<unsigned char>(item.front()));
}

}  // namespace

std::vector<int> groupVertices(const Mesh& mesh, const std::string& name,
                               const std::string& source) {
  const auto found = std::find(mesh.groupNames.begin(), mesh.groupNames.end(), name);
  if (found == mesh.groupNames.end()) {
    DS_THROW(kInput, source, ": the mesh has no group '", name,
             "' (its groups: ", knownGroups(mesh),
             "); name a group of the OBJ's g lines or give vertex indices");
  }
  const int group = static_cast<int>(found - mesh.groupNames.begin());
  std::vector<int> vertices;
  for (int f = 0; f < mesh.faceCount(); ++f) {
    if (mesh.faceGroup[f] == group) {
      vertices.insert(vertices.end(), mesh.faceVertices.begin() + mesh.faceStart[f],
                      mesh.faceVertices.begin() + mesh.faceStart[f + 1]);
    }
  }
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  if (vertices.empty()) {
    DS_THROW(kInput, source, ": group '", name, "' has no faces, so it names no vertex");
  }
  return vertices;
}

std::vector<int> selectVertices(const Mesh& mesh, const std::string& spec,
                                const std::string& source) {
  const int count = mesh.vertexCount();
  std::vector<int> vertices;
  if (trimSpaces(spec).empty() || trimSpaces(spec) == "all") {
    vertices.resize(static_cast<std::size_t>(count));
    for (int v = 0; v < count; ++v) {
      vertices[v] = v;
    }
    return vertices;
  }
  std::size_t start = 0;
  while (start <= spec.size()) {
    const std::size_t comma = std::min(spec.find(',', start), spec.size());
    const std::string item = trimSpaces(spec.substr(start, comma - start));
    start = comma + 1;
    if (item.empty()) {
      continue;
    }
    if (!isIndexItem(item)) {
      const std::vector<int> group = groupVertices(mesh, item, source);
      vertices.insert(vertices.end(), group.begin(), group.end());
      continue;
    }
    const std::size_t dash = item.find('-');
    long first = 0, last = 0;
    try {
      first = std::stol(item.substr(0, dash));
      last = dash == std::string::npos ? first : std::stol(item.substr(dash + 1));
    } catch (const std::exception&) {
      DS_THROW(kInput, source, ": '", item, "' is not a vertex index or range (e.g. 0-99)");
    }
    if (last < first || first < 0 || last >= count) {
      DS_THROW(kInput, source, ": vertex range '", item, "' is outside 0-", count - 1,
               " (the mesh has ", count, " vertices)");
    }
    for (long v = first; v <= last; ++v) {
      vertices.push_back(static_cast<int>(v));
    }
  }
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  if (vertices.empty()) {
    DS_THROW(kInput, source, ": '", spec, "' names no vertex");
  }
  return vertices;
}

}  // namespace drivenshape
