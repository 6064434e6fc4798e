// SPDX-License-Identifier: Apache-2.0
// Binding masks: the tables and the JSON file format documented in drivenshape/correction.h.

#include <algorithm>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <drivenshape/binding.h>
#include <drivenshape/error.h>

#include "atomic_file.h"

#include "json_text.h"

namespace drivenshape {

BindingMask BindingMask::all(int drivenVertexCount) {
  return BindingMask(std::vector<int>(static_cast<std::size_t>(std::max(drivenVertexCount, 0)), -1),
                     {});
}

BindingMask::BindingMask(std::vector<int> vertexClass, std::vector<std::vector<int>> classTriangles)
    : mVertexClass(std::move(vertexClass)), mClassTriangles(std::move(classTriangles)) {
  const int classCount = static_cast<int>(mClassTriangles.size());
  for (std::size_t v = 0; v < mVertexClass.size(); ++v) {
    if (mVertexClass[v] < -1 || mVertexClass[v] >= classCount) {
      DS_THROW(kInput, "binding mask: driven vertex ", v, " has class ", mVertexClass[v],
               " but there are ", classCount, " classes");
    }
  }
  for (std::size_t c = 0; c < mClassTriangles.size(); ++c) {
    std::vector<int>& triangles = mClassTriangles[c];
    std::sort(triangles.begin(), triangles.end());
    triangles.erase(std::unique(triangles.begin(), triangles.end()), triangles.end());
    if (triangles.empty()) {
      DS_THROW(kInput, "binding mask: class ", c, " allows no driver triangle");
    }
    if (triangles.front() < 0) {
      DS_THROW(kInput, "binding mask: class ", c, " names negative triangle ", triangles.front());
    }
  }
}

bool BindingMask::allows(int vertex, int triangle) const {
  const int c = mVertexClass[static_cast<std::size_t>(vertex)];
  if (c < 0) {
    return true;
  }
  const std::vector<int>& triangles = mClassTriangles[static_cast<std::size_t>(c)];
  return std::binary_search(triangles.begin(), triangles.end(), triangle);
}

bool BindingMask::isAll() const {
  return std::all_of(mVertexClass.begin(), mVertexClass.end(), [](int c) { return c < 0; });
}

namespace {

using Json = nlohmann::json;

/// Parses one mask document; every error names the source and the entry.
class MaskParser {
 public:
  MaskParser(const std::string& source, const Mesh& driver, const Mesh& driven)
      : mSource(source), mDriver(driver), mDriven(driven) {}

  BindingMask parse(const std::string& text) {
    const Json document = parseJsonText(text, mSource);
    if (!document.is_object()) {
      fail("", "must hold a JSON object with a \"bindings\" list");
    }
    checkKeys(document, "", {"version", "bindings"});
    if (document.contains("version") &&
        (!document["version"].is_number_integer() || document["version"].get<long long>() != 1)) {
      fail("", "has \"version\" ", document["version"].dump(), "; this tool reads version 1");
    }
    if (!document.contains("bindings") || !document["bindings"].is_array()) {
      fail("", "must hold a \"bindings\" list");
    }

    std::vector<int> vertexClass(static_cast<std::size_t>(mDriven.vertexCount()), -1);
    std::vector<int> vertexEntry(static_cast<std::size_t>(mDriven.vertexCount()), -1);
    std::vector<std::vector<int>> classes;
    std::map<std::vector<int>, int> classOf;
    const Json& bindings = document["bindings"];
    for (std::size_t e = 0; e < bindings.size(); ++e) {
      mEntry = "bindings[" + std::to_string(e) + "]";
      const Json& entry = bindings[e];
      if (!entry.is_object()) {
        fail(mEntry, "must be an object with \"driven\" and \"driver\"");
      }
      checkKeys(entry, mEntry, {"name", "driven", "driver"});
      if (entry.contains("name")) {
        if (!entry["name"].is_string()) {
          fail(mEntry, "has a \"name\" that is not a string");
        }
        mEntry += " (\"" + entry["name"].get<std::string>() + "\")";
      }
      if (!entry.contains("driven") || !entry.contains("driver")) {
        fail(mEntry, "needs both \"driven\" and \"driver\"");
      }
      const std::vector<int> vertices = drivenVertices(entry["driven"]);
      const std::vector<int> triangles = driverTriangles(entry["driver"]);
      auto found = classOf.find(triangles);
      int c = 0;
      if (found == classOf.end()) {
        c = static_cast<int>(classes.size());
        classes.push_back(triangles);
        classOf.emplace(triangles, c);
      } else {
        c = found->second;
      }
      for (int v : vertices) {
        const int earlier = vertexEntry[static_cast<std::size_t>(v)];
        if (earlier >= 0) {
          fail(mEntry, "names driven vertex ", v, ", which bindings[", earlier,
               "] already binds; a vertex may appear in one entry only");
        }
        vertexEntry[static_cast<std::size_t>(v)] = static_cast<int>(e);
        vertexClass[static_cast<std::size_t>(v)] = c;
      }
    }
    return BindingMask(std::move(vertexClass), std::move(classes));
  }

 private:
  template <typename... Args>
  [[noreturn]] void fail(const std::string& where, const Args&... args) const {
    DS_THROW(kInput, "binding mask ", mSource, where.empty() ? "" : ": ", where, " ", args...);
  }

  void checkKeys(const Json& object, const std::string& where,
                 std::initializer_list<const char*> allowed) const {
    for (auto it = object.begin(); it != object.end(); ++it) {
      if (it.key() == "comment") {
        continue;
      }
      if (std::none_of(allowed.begin(), allowed.end(),
                       [&](const char* key) { return it.key() == key; })) {
        std::string names;
        for (const char* key : allowed) {
          names +=
              names.empty() ? std::string("\"") + key + "\"" : std::string(", \"") + key + "\"";
        }
        fail(where, "has unknown key \"", it.key(), "\" (expected ", names, ", \"comment\")");
      }
    }
  }

  static std::string knownGroups(const Mesh& mesh) {
    std::string names;
    for (const std::string& name : mesh.groupNames) {
      names += (names.empty() ? "\"" : ", \"") + name + "\"";
    }
    return names.empty() ? "(none)" : names;
  }

  /// Face ids of the group `name` of `mesh`; errors on unknown and empty groups.
  std::vector<int> groupFaces(const Mesh& mesh, const char* side, const std::string& name) const {
    const auto it = std::find(mesh.groupNames.begin(), mesh.groupNames.end(), name);
    if (it == mesh.groupNames.end()) {
      fail(mEntry, "names ", side, " group \"", name, "\", which the ", side,
           " mesh does not have; its groups are ", knownGroups(mesh));
    }
    const int group = static_cast<int>(it - mesh.groupNames.begin());
    std::vector<int> faces;
    for (int f = 0; f < mesh.faceCount(); ++f) {
      if (mesh.faceGroup[static_cast<std::size_t>(f)] == group) {
        faces.push_back(f);
      }
    }
    if (faces.empty()) {
      fail(mEntry, "names ", side, " group \"", name, "\", which has no faces");
    }
    return faces;
  }

  /// Group names: a string or a list of strings.
  std::vector<std::string> names(const Json& value, const char* what) const {
    std::vector<std::string> out;
    if (value.is_string()) {
      out.push_back(value.get<std::string>());
    } else if (value.is_array()) {
      for (const Json& item : value) {
        if (!item.is_string()) {
          fail(mEntry, what, " must list group names (strings); found ", item.dump());
        }
        out.push_back(item.get<std::string>());
      }
    } else {
      fail(mEntry, what, " must be a group name or a list of group names; found ", value.dump());
    }
    if (out.empty()) {
      fail(mEntry, what, " is an empty list");
    }
    return out;
  }

  /// An index list: integers and "a-b" inclusive ranges, each within [0, limit).
  std::vector<int> indices(const Json& value, const char* what, int limit) const {
    if (!value.is_array()) {
      fail(mEntry, what, " must be a list of indices and \"a-b\" ranges; found ", value.dump());
    }
    std::vector<int> out;
    for (const Json& item : value) {
      long long first = 0;
      long long last = 0;
      if (item.is_number_integer()) {
        first = last = item.get<long long>();
      } else if (item.is_string()) {
        const std::string text = item.get<std::string>();
        std::istringstream stream(text);
        char dash = 0;
        if (!(stream >> first >> dash >> last) || dash != '-' || !stream.eof() || last < first) {
          fail(mEntry, what, " has \"", text, "\", which is not a range \"a-b\" with a <= b");
        }
      } else {
        fail(mEntry, what, " must hold integers and \"a-b\" ranges; found ", item.dump());
      }
      if (first < 0 || last >= limit) {
        fail(mEntry, what, " has index ", first < 0 ? first : last, " out of range; valid are 0..",
             limit - 1);
      }
      for (long long i = first; i <= last; ++i) {
        out.push_back(static_cast<int>(i));
      }
    }
    if (out.empty()) {
      fail(mEntry, what, " is an empty list");
    }
    return out;
  }

  std::vector<int> drivenVertices(const Json& value) const {
    std::vector<int> faces;
    std::vector<int> vertices;
    if (value.is_object()) {
      checkKeys(value, mEntry + " \"driven\"", {"groups", "vertices"});
      if (!value.contains("groups") && !value.contains("vertices")) {
        fail(mEntry, "\"driven\" needs \"groups\" or \"vertices\"");
      }
      if (value.contains("groups")) {
        for (const std::string& name : names(value["groups"], "\"driven\".\"groups\"")) {
          const std::vector<int> more = groupFaces(mDriven, "driven", name);
          faces.insert(faces.end(), more.begin(), more.end());
        }
      }
      if (value.contains("vertices")) {
        vertices = indices(value["vertices"], "\"driven\".\"vertices\"", mDriven.vertexCount());
      }
    } else {
      for (const std::string& name : names(value, "\"driven\"")) {
        const std::vector<int> more = groupFaces(mDriven, "driven", name);
        faces.insert(faces.end(), more.begin(), more.end());
      }
    }
    for (int f : faces) {
      for (int k = mDriven.faceStart[static_cast<std::size_t>(f)];
           k < mDriven.faceStart[static_cast<std::size_t>(f) + 1]; ++k) {
        vertices.push_back(mDriven.faceVertices[static_cast<std::size_t>(k)]);
      }
    }
    std::sort(vertices.begin(), vertices.end());
    vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
    return vertices;
  }

  std::vector<int> driverTriangles(const Json& value) const {
    std::vector<int> faces;
    if (value.is_object()) {
      checkKeys(value, mEntry + " \"driver\"", {"groups", "faces"});
      if (!value.contains("groups") && !value.contains("faces")) {
        fail(mEntry, "\"driver\" needs \"groups\" or \"faces\"");
      }
      if (value.contains("groups")) {
        for (const std::string& name : names(value["groups"], "\"driver\".\"groups\"")) {
          const std::vector<int> more = groupFaces(mDriver, "driver", name);
          faces.insert(faces.end(), more.begin(), more.end());
        }
      }
      if (value.contains("faces")) {
        const std::vector<int> more =
            indices(value["faces"], "\"driver\".\"faces\"", mDriver.faceCount());
        faces.insert(faces.end(), more.begin(), more.end());
      }
    } else {
      for (const std::string& name : names(value, "\"driver\"")) {
        const std::vector<int> more = groupFaces(mDriver, "driver", name);
        faces.insert(faces.end(), more.begin(), more.end());
      }
    }
    std::sort(faces.begin(), faces.end());
    faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
    std::vector<int> triangles;
    for (int t = 0; t < mDriver.triangleCount(); ++t) {
      if (std::binary_search(faces.begin(), faces.end(),
                             mDriver.triangleFace[static_cast<std::size_t>(t)])) {
        triangles.push_back(t);
      }
    }
    if (triangles.empty()) {
      fail(mEntry, "\"driver\" selects ", faces.size(),
           " faces but no triangles (faces of fewer than three vertices?)");
    }
    return triangles;
  }

  std::string mSource;
  const Mesh& mDriver;
  const Mesh& mDriven;
  std::string mEntry;
};

}  // namespace

BindingMask parseBindingMask(const std::string& jsonText, const std::string& source,
                             const Mesh& driver, const Mesh& driven) {
  if (static_cast<int>(driver.triangleFace.size()) != driver.triangleCount()) {
    DS_THROW(kInternal, "binding mask ", source,
             ": the driver mesh is not triangulated (Mesh::triangulate)");
  }
  return MaskParser(source, driver, driven).parse(jsonText);
}

BindingMask readBindingMask(const std::string& path, const Mesh& driver, const Mesh& driven) {
  return parseBindingMask(readWholeFile(path, "binding mask"), path, driver, driven);
}

}  // namespace drivenshape
