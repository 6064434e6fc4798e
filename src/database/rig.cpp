// SPDX-License-Identifier: Apache-2.0
// A rig's parts for the pose model (drivenshape/pose_model.h): each driver vertex goes to the
// bone of its largest skin weight; a part's parent is the nearest ancestor bone that is a part.

#include <drivenshape/pose_model.h>

#include <algorithm>
#include <functional>
#include <map>
#include <set>

#include <drivenshape/error.h>

#include "atomic_file.h"

#include "json_text.h"

namespace drivenshape {
namespace {

/// Bone parents (by name, "" for a root) from the rig's optional bones list; `fail` refuses a
/// malformed entry, a bone that is its own parent and a parent that is neither one of `names`
/// nor a bone of the list (a bone that deforms nothing, such as a root, has no weights).
std::map<std::string, std::string> boneParents(
    const nlohmann::json& rig, const std::vector<std::string>& names,
    const std::function<void(const std::string&)>& fail) {
  std::map<std::string, std::string> parentName;
  if (!rig.contains("bones")) {
    return parentName;
  }
  if (!rig.at("bones").is_array()) {
    fail("bones is not an array");
  }
  std::vector<std::string> known = names;
  for (const nlohmann::json& b : rig.at("bones")) {
    if (!b.is_object() || !b.contains("name") || !b.at("name").is_string()) {
      fail("a bone has no name");
    }
    known.push_back(b.at("name").get<std::string>());
  }
  for (const nlohmann::json& b : rig.at("bones")) {
    const std::string name = b.at("name").get<std::string>();
    const nlohmann::json parent = b.value("parent", nlohmann::json());
    if (!parent.is_null() && !parent.is_string()) {
      fail("the parent of bone '" + name + "' is not a name");
    }
    const std::string parentText = parent.is_null() ? "" : parent.get<std::string>();
    if (parentText == name) {
      fail("bone '" + name + "' is its own parent");
    }
    if (!parentText.empty() && std::find(known.begin(), known.end(), parentText) == known.end()) {
      fail("the parent '" + parentText + "' of bone '" + name +
           "' is neither in bone_names nor a bone of bones");
    }
    parentName[name] = parentText;
  }
  return parentName;
}

}  // namespace

void parseRigParts(const std::string& text, const std::string& source, int driverVertexCount,
                   std::vector<int>& partOf, std::vector<int>& parentOf) {
  const nlohmann::json rig = parseJsonText(text, source);
  const auto fail = [&](const std::string& what) {
    DS_THROW(kInput, source, ": ", what,
             " (a rig file holds bone_names, bones [{name, parent}] and driver_weights, one row "
             "of bone weights per driver vertex; see docs/formats.md)");
  };
  if (!rig.is_object() || !rig.contains("bone_names") || !rig.contains("driver_weights") ||
      !rig.at("bone_names").is_array() || !rig.at("driver_weights").is_array()) {
    fail("no bone_names or driver_weights array");
  }
  std::vector<std::string> names;
  for (const nlohmann::json& name : rig.at("bone_names")) {
    if (!name.is_string()) {
      fail("a bone name is not a string");
    }
    names.push_back(name.get<std::string>());
  }
  if (names.empty() || std::set<std::string>(names.begin(), names.end()).size() != names.size()) {
    fail("bone_names is empty or names a bone twice");
  }
  const nlohmann::json& rows = rig.at("driver_weights");
  if (static_cast<long long>(rows.size()) != driverVertexCount) {
    fail("driver_weights has " + std::to_string(rows.size()) + " rows for a driver of " +
         std::to_string(driverVertexCount) + " vertices");
  }
  std::vector<int> bone(static_cast<std::size_t>(driverVertexCount));
  for (int v = 0; v < driverVertexCount; ++v) {
    const nlohmann::json& row = rows[static_cast<std::size_t>(v)];
    if (!row.is_array() || row.size() != names.size()) {
      fail("driver_weights row " + std::to_string(v) + " does not hold one weight per bone");
    }
    double best = -1.0;
    for (std::size_t b = 0; b < names.size(); ++b) {
      if (!row[b].is_number()) {
        fail("driver_weights row " + std::to_string(v) + " holds a weight that is not a number");
      }
      const double w = row[b].get<double>();
      if (w > best) {
        best = w;
        bone[static_cast<std::size_t>(v)] = static_cast<int>(b);
      }
    }
    if (!(best > 0.0)) {
      fail("driver_weights row " + std::to_string(v) + " has no positive weight: driver vertex " +
           std::to_string(v) + " follows no bone");
    }
  }
  const std::map<std::string, std::string> parentName = boneParents(rig, names, fail);
  // Parts: the bones some vertex uses, in bone order.
  std::vector<int> partOfBone(names.size(), -1);
  int parts = 0;
  for (std::size_t b = 0; b < names.size(); ++b) {
    if (std::find(bone.begin(), bone.end(), static_cast<int>(b)) != bone.end()) {
      partOfBone[b] = parts++;
    }
  }
  partOf.resize(bone.size());
  for (std::size_t v = 0; v < bone.size(); ++v) {
    partOf[v] = partOfBone[static_cast<std::size_t>(bone[v])];
  }
  parentOf.assign(static_cast<std::size_t>(parts), -1);
  for (std::size_t b = 0; b < names.size(); ++b) {
    if (partOfBone[b] < 0) {
      continue;
    }
    // The nearest ancestor that is a part (a cycle in the bones list ends the walk).
    std::set<std::string> seen = {names[b]};
    auto it = parentName.find(names[b]);
    while (it != parentName.end() && !it->second.empty() && seen.insert(it->second).second) {
      const auto named = std::find(names.begin(), names.end(), it->second);
      if (named != names.end() &&
          partOfBone[static_cast<std::size_t>(named - names.begin())] >= 0) {
        parentOf[static_cast<std::size_t>(partOfBone[b])] =
            partOfBone[static_cast<std::size_t>(named - names.begin())];
        break;
      }
      it = parentName.find(it->second);
    }
  }
  // Parts whose bones' parents loop through other parts form a cycle: refuse it.
  for (int p = 0; p < parts; ++p) {
    int q = p;
    for (int steps = 0; q >= 0; ++steps) {
      if (steps > parts) {
        fail("the parents of bone '" +
             names[static_cast<std::size_t>(std::find(partOfBone.begin(), partOfBone.end(), p) -
                                            partOfBone.begin())] +
             "' loop; each bone needs a chain of parents that ends");
      }
      q = parentOf[static_cast<std::size_t>(q)];
    }
  }
}

void readRigParts(const std::string& path, int driverVertexCount, std::vector<int>& partOf,
                  std::vector<int>& parentOf) {
  parseRigParts(readWholeFile(path, "rig"), path, driverVertexCount, partOf, parentOf);
}

}  // namespace drivenshape
