// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/regions.h>

#include <algorithm>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <queue>
#include <sstream>

#include <drivenshape/error.h>
#include <drivenshape/mesh.h>

#include "atomic_file.h"

#include "json_text.h"

namespace drivenshape {
namespace {

using nlohmann::json;

constexpr int kUnreached = std::numeric_limits<int>::max();

void checkKeys(const json& object, const std::vector<std::string>& allowed,
               const std::string& where) {
  for (const auto& item : object.items()) {
    if (item.key() != "comment" &&
        std::find(allowed.begin(), allowed.end(), item.key()) == allowed.end()) {
      std::string list;
      for (const std::string& key : allowed) {
        list += (list.empty() ? "" : ", ") + key;
      }
      DS_THROW(kInput, where, ": unknown key '", item.key(), "' (allowed: ", list, ")");
    }
  }
}

/// Vertices named by a "driver"/"driven" value: a group, a list of groups, or an object.
std::vector<int> namedVertices(const json& value, const Mesh& mesh, const std::string& where) {
  std::vector<int> vertices;
  auto addGroups = [&](const json& groups) {
    if (groups.is_string()) {
      const std::vector<int> g = groupVertices(mesh, groups.get<std::string>(), where);
      vertices.insert(vertices.end(), g.begin(), g.end());
      return;
    }
    if (!groups.is_array()) {
      DS_THROW(kInput, where, ": expected a group name or a list of group names");
    }
    for (const json& name : groups) {
      if (!name.is_string()) {
        DS_THROW(kInput, where, ": group names must be strings");
      }
      const std::vector<int> g = groupVertices(mesh, name.get<std::string>(), where);
      vertices.insert(vertices.end(), g.begin(), g.end());
    }
  };
  if (value.is_object()) {
    checkKeys(value, {"groups", "vertices"}, where);
    if (value.contains("groups")) {
      addGroups(value.at("groups"));
    }
    if (value.contains("vertices")) {
      const json& list = value.at("vertices");
      if (!list.is_array()) {
        DS_THROW(kInput, where, ".vertices: expected a list of indices or \"a-b\" ranges");
      }
      std::string spec;
      for (const json& item : list) {
        if (item.is_number_integer()) {
          spec += std::to_string(item.get<long>()) + ",";
        } else if (item.is_string()) {
          spec += item.get<std::string>() + ",";
        } else {
          DS_THROW(kInput, where, ".vertices: '", item.dump(), "' is not an index or a range");
        }
      }
      if (!spec.empty()) {
        for (char c : spec) {
          if (!(std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == ',')) {
            DS_THROW(kInput, where, ".vertices: '", spec, "' holds something other than indices");
          }
        }
        const std::vector<int> v = selectVertices(mesh, spec, where + ".vertices");
        vertices.insert(vertices.end(), v.begin(), v.end());
      }
    }
  } else {
    addGroups(value);
  }
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  if (vertices.empty()) {
    DS_THROW(kInput, where, ": names no vertex; give a group or vertex indices");
  }
  return vertices;
}

/// Vertex neighbours along polygon edges (not the fan diagonals).
std::vector<std::vector<int>> adjacency(const Mesh& mesh) {
  std::vector<std::vector<int>> next(static_cast<std::size_t>(mesh.vertexCount()));
  for (int f = 0; f < mesh.faceCount(); ++f) {
    const int begin = mesh.faceStart[f], end = mesh.faceStart[f + 1];
    for (int i = begin; i < end; ++i) {
      const int a = mesh.faceVertices[i];
      const int b = mesh.faceVertices[i + 1 < end ? i + 1 : begin];
      next[a].push_back(b);
      next[b].push_back(a);
    }
  }
  for (auto& list : next) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }
  return next;
}

/// Edge-ring distance from every vertex to the nearest vertex with source[v] true.
std::vector<int> ringDistance(const std::vector<std::vector<int>>& next,
                              const std::vector<char>& source) {
  std::vector<int> distance(next.size(), kUnreached);
  std::queue<int> queue;
  for (std::size_t v = 0; v < next.size(); ++v) {
    if (source[v]) {
      distance[v] = 0;
      queue.push(static_cast<int>(v));
    }
  }
  while (!queue.empty()) {
    const int v = queue.front();
    queue.pop();
    for (int w : next[v]) {
      if (distance[w] == kUnreached) {
        distance[w] = distance[v] + 1;
        queue.push(w);
      }
    }
  }
  return distance;
}

double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

}  // namespace

std::vector<float> regionFalloff(const Mesh& mesh, const std::vector<std::vector<int>>& sets,
                                 int falloff) {
  const int vertexCount = mesh.vertexCount();
  const int count = static_cast<int>(sets.size());
  const auto next = adjacency(mesh);
  std::vector<double> raw(static_cast<std::size_t>(count) * vertexCount, 0.0);
  for (int r = 0; r < count; ++r) {
    if (sets[r].empty()) {
      continue;
    }
    std::vector<char> inside(static_cast<std::size_t>(vertexCount), 0);
    for (int v : sets[r]) {
      inside[v] = 1;
    }
    std::vector<char> outside(inside.size());
    std::transform(inside.begin(), inside.end(), outside.begin(),
                   [](char c) { return static_cast<char>(!c); });
    const std::vector<int> toInside = ringDistance(next, inside);
    const std::vector<int> toOutside = ringDistance(next, outside);
    for (int v = 0; v < vertexCount; ++v) {
      // Signed distance to the border in rings; unreached = far away on that side.
      const double big = 1e9;
      const double s = inside[v] ? (toOutside[v] == kUnreached ? big : toOutside[v] - 0.5)
                                 : (toInside[v] == kUnreached ? -big : 0.5 - toInside[v]);
      raw[static_cast<std::size_t>(r) * vertexCount + v] =
          falloff <= 0 ? (s > 0 ? 1.0 : 0.0) : smoothstep((s + falloff) / (2.0 * falloff));
    }
  }
  std::vector<float> mix(raw.size(), 0.0f);
  for (int v = 0; v < vertexCount; ++v) {
    double sum = 0.0;
    for (int r = 0; r < count; ++r) {
      sum += raw[static_cast<std::size_t>(r) * vertexCount + v];
    }
    if (!(sum > 0.0)) {
      DS_THROW(kInternal, "regionFalloff: vertex ", v, " is in no region");
    }
    for (int r = 0; r < count; ++r) {
      mix[static_cast<std::size_t>(r) * vertexCount + v] =
          static_cast<float>(raw[static_cast<std::size_t>(r) * vertexCount + v] / sum);
    }
  }
  return mix;
}

RegionSet parseRegions(const std::string& jsonText, const std::string& source, const Mesh& driver,
                       const Mesh& driven) {
  const json root = parseJsonText(jsonText, source);
  if (!root.is_object()) {
    DS_THROW(kInput, source, ": expected an object with a \"regions\" list");
  }
  checkKeys(root, {"version", "falloff", "regions"}, source);
  if (root.contains("version") && root.at("version") != 1) {
    DS_THROW(kInput, source, ": version ", root.at("version").dump(),
             " is not supported (this tool reads version 1)");
  }
  RegionSet set;
  if (root.contains("falloff")) {
    const json& falloff = root.at("falloff");
    if (!falloff.is_number_integer() || falloff.get<long>() < 0 || falloff.get<long>() > 1000) {
      DS_THROW(kInput, source, ": \"falloff\" must be a whole number of edge rings, 0-1000");
    }
    set.falloff = falloff.get<int>();
  }
  if (!root.contains("regions") || !root.at("regions").is_array() || root.at("regions").empty()) {
    DS_THROW(kInput, source, ": needs a non-empty \"regions\" list");
  }
  std::vector<int> driverOwner(static_cast<std::size_t>(driver.vertexCount()), -1);
  std::vector<int> drivenOwner(static_cast<std::size_t>(driven.vertexCount()), -1);
  const json& list = root.at("regions");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = source + ": regions[" + std::to_string(i) + "]";
    const json& entry = list[i];
    if (!entry.is_object()) {
      DS_THROW(kInput, where, ": expected an object with \"driver\" and \"driven\"");
    }
    checkKeys(entry, {"name", "driver", "driven"}, where);
    Region region;
    region.name = entry.contains("name") && entry.at("name").is_string()
                      ? entry.at("name").get<std::string>()
                      : "region" + std::to_string(i);
    if (!entry.contains("driver") || !entry.contains("driven")) {
      DS_THROW(kInput, where, " ('", region.name, "'): needs both \"driver\" and \"driven\"");
    }
    region.driverVertices = namedVertices(entry.at("driver"), driver, where + ".driver");
    region.drivenVertices = namedVertices(entry.at("driven"), driven, where + ".driven");
    auto claim = [&](std::vector<int>& owner, const std::vector<int>& vertices, const char* mesh) {
      for (int v : vertices) {
        if (owner[v] >= 0) {
          DS_THROW(kInput, where, " ('", region.name, "'): ", mesh, " vertex ", v,
                   " is already in region '", set.regions[owner[v]].name,
                   "'; regions must not overlap");
        }
        owner[v] = static_cast<int>(i);
      }
    };
    claim(driverOwner, region.driverVertices, "driver");
    claim(drivenOwner, region.drivenVertices, "driven");
    set.regions.push_back(std::move(region));
  }
  // Uncovered vertices form the implicit "rest" region, weighted on every driver row.
  Region rest;
  rest.name = "rest";
  std::vector<int> restDriver, restDriven;
  for (int v = 0; v < driver.vertexCount(); ++v) {
    if (driverOwner[v] < 0) {
      restDriver.push_back(v);
    }
  }
  for (int v = 0; v < driven.vertexCount(); ++v) {
    if (drivenOwner[v] < 0) {
      restDriven.push_back(v);
    }
  }
  std::vector<std::vector<int>> driverSets, drivenSets;
  for (const Region& region : set.regions) {
    driverSets.push_back(region.driverVertices);
    drivenSets.push_back(region.drivenVertices);
  }
  if (!restDriver.empty() || !restDriven.empty()) {
    driverSets.push_back(restDriver);
    drivenSets.push_back(restDriven);
    for (int v = 0; v < driver.vertexCount(); ++v) {
      rest.driverVertices.push_back(v);
    }
    rest.drivenVertices = restDriven;
    set.regions.push_back(std::move(rest));
  }
  set.driverMix = regionFalloff(driver, driverSets, set.falloff);
  set.drivenMix = regionFalloff(driven, drivenSets, set.falloff);
  return set;
}

RegionSet readRegions(const std::string& path, const Mesh& driver, const Mesh& driven) {
  return parseRegions(readWholeFile(path, "region file"), path, driver, driven);
}

}  // namespace drivenshape
