// SPDX-License-Identifier: Apache-2.0
// Weight maps (one number in [0, 1] per driven vertex): JSON arrays, one-channel point-cache
// EXRs, OBJ face groups, and the edge-ring falloff that softens them.

#include <drivenshape/weight_map.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include <drivenshape/error.h>

#include "atomic_file.h"

#include "json_text.h"

#include "exr_common.h"

namespace drivenshape {
namespace {

using Json = nlohmann::json;

constexpr const char* kGroupPrefix = "group:";
constexpr const char* kWeightChannel = "W";
constexpr const char* kAttrVertexCount = "dsVertexCount";
constexpr int kMaxRings = 64;

bool endsWith(const std::string& text, const std::string& suffix) {
  if (text.size() < suffix.size()) {
    return false;
  }
  return std::equal(suffix.rbegin(), suffix.rend(), text.rbegin(), [](char a, char b) {
    return std::tolower(static_cast<unsigned char>(a)) ==
           std::tolower(static_cast<unsigned char>(b));
  });
}

/// Every value must be a number in [0, 1]; the message names the source, the index and value.
void checkRange(const std::vector<float>& weights, const std::string& source) {
  for (std::size_t i = 0; i < weights.size(); ++i) {
    const float w = weights[i];
    if (std::isnan(w)) {
      DS_THROW(kInput, source, ": weight of vertex ", i,
               " is NaN; weights are numbers in [0, 1] (1 = fully on)");
    }
    if (!(w >= 0.0f && w <= 1.0f)) {
      DS_THROW(kInput, source, ": weight of vertex ", i, " is ", w,
               ", outside [0, 1]; rescale the map (1 = fully on, 0 = off)");
    }
  }
}

void checkLength(std::size_t count, int vertexCount, const std::string& source) {
  if (count != static_cast<std::size_t>(vertexCount)) {
    DS_THROW(kInput, source, ": the map has ", count, " weights but the driven mesh has ",
             vertexCount,
             " vertices; a weight map holds one value per driven vertex, in the mesh's order");
  }
}

std::vector<float> readJsonMap(const std::string& path, int vertexCount, const std::string& what) {
  const std::string text = readWholeFile(path, what);
  const Json json = parseJsonText(text, what + " '" + path + "'");
  const Json* array = &json;
  if (json.is_object()) {
    for (const auto& item : json.items()) {
      if (item.key() != "weights" && item.key() != "comment") {
        DS_THROW(kInput, what, " '", path, "': unknown key '", item.key(),
                 "'; a weight-map object has \"weights\" (and optionally \"comment\")");
      }
    }
    if (!json.contains("weights")) {
      DS_THROW(kInput, what, " '", path, "': no \"weights\" array");
    }
    array = &json["weights"];
  }
  if (!array->is_array()) {
    DS_THROW(kInput, what, " '", path,
             "' must be a JSON array of numbers, one per driven vertex (or {\"weights\": [...]})");
  }
  checkLength(array->size(), vertexCount, what + " '" + path + "'");
  std::vector<float> weights(array->size());
  for (std::size_t i = 0; i < array->size(); ++i) {
    const Json& value = (*array)[i];
    if (!value.is_number()) {
      DS_THROW(kInput, what, " '", path, "': weight of vertex ", i, " is ", value.dump(),
               ", not a number in [0, 1]");
    }
    weights[i] = static_cast<float>(value.get<double>());
  }
  checkRange(weights, what + " '" + path + "'");
  return weights;
}

std::vector<float> readExrMap(const std::string& path, int vertexCount, const std::string& what) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    DS_THROW(kInput, what, " '", path, "' does not exist");
  }
  const std::string source = what + " '" + path + "'";
  try {
    const auto file = exr_detail::openExr(path, "weight-map");
    const Imf::Header& header = file->header();
    const auto* count = header.findTypedAttribute<Imf::IntAttribute>(kAttrVertexCount);
    if (count == nullptr) {
      DS_THROW(kInput, source, ": not a point-cache weight map (no ", kAttrVertexCount,
               " attribute); write it with the point-cache pixel layout (see docs/formats.md)");
    }
    checkLength(static_cast<std::size_t>(std::max(0, count->value())), vertexCount, source);
    // Channel W, or the only channel besides the coverage A.
    std::string channel;
    std::vector<std::string> names;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
      names.emplace_back(it.name());
    }
    if (header.channels().findChannel(kWeightChannel) != nullptr) {
      channel = kWeightChannel;
    } else {
      std::vector<std::string> candidates;
      for (const std::string& name : names) {
        if (name != exr_detail::kCoverageChannel) {
          candidates.push_back(name);
        }
      }
      if (candidates.size() != 1) {
        std::ostringstream list;
        for (const std::string& name : names) {
          list << (list.tellp() > 0 ? ", " : "") << name;
        }
        DS_THROW(kInput, source, ": no channel W and ", candidates.size(), " other channels (",
                 list.str(), "); a weight map has one channel, W");
      }
      channel = candidates.front();
    }
    const Imath::Box2i& window = header.dataWindow();
    const long long width = static_cast<long long>(window.max.x) - window.min.x + 1;
    const long long height = static_cast<long long>(window.max.y) - window.min.y + 1;
    if (width <= 0 || height <= 0 || width * height < vertexCount ||
        (vertexCount + width - 1) / width != height) {
      DS_THROW(kInput, source, ": the image is ", width, "x", height, " pixels, not the ",
               "point-cache layout of ", vertexCount, " vertices");
    }
    std::vector<float> pixels(static_cast<std::size_t>(width * height), 0.0f);
    const std::ptrdiff_t origin = static_cast<std::ptrdiff_t>(window.min.x) +
                                  static_cast<std::ptrdiff_t>(window.min.y) * width;
    Imf::FrameBuffer frameBuffer;
    frameBuffer.insert(channel,
                       Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(pixels.data() - origin),
                                  sizeof(float), sizeof(float) * static_cast<std::size_t>(width)));
    file->setFrameBuffer(frameBuffer);
    file->readPixels(window.min.y, window.max.y);
    pixels.resize(static_cast<std::size_t>(vertexCount));
    checkRange(pixels, source);
    return pixels;
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    DS_THROW(kInput, "cannot read ", source, ": ", e.what());
  }
}

std::vector<float> groupMap(const std::string& names, const Mesh& mesh, const std::string& what) {
  std::vector<std::string> wanted;
  std::stringstream list(names);
  std::string name;
  while (std::getline(list, name, ',')) {
    if (name.empty()) {
      DS_THROW(kUsage, what, " 'group:", names,
               "' has an empty group name; write group:NAME or group:NAME,NAME");
    }
    wanted.push_back(name);
  }
  if (wanted.empty()) {
    DS_THROW(kUsage, what, " 'group:' names no group; write group:NAME or group:NAME,NAME");
  }
  std::set<int> groupIds;
  for (const std::string& group : wanted) {
    const auto found = std::find(mesh.groupNames.begin(), mesh.groupNames.end(), group);
    if (found == mesh.groupNames.end()) {
      std::ostringstream known;
      for (const std::string& knownName : mesh.groupNames) {
        known << (known.tellp() > 0 ? ", " : "") << knownName;
      }
      DS_THROW(kInput, what, ": the driven mesh has no group '", group,
               "'; its groups are: ", known.str().empty() ? "(none)" : known.str());
    }
    groupIds.insert(static_cast<int>(found - mesh.groupNames.begin()));
  }
  std::vector<float> weights(static_cast<std::size_t>(mesh.vertexCount()), 0.0f);
  bool any = false;
  for (int f = 0; f < mesh.faceCount(); ++f) {
    if (groupIds.count(mesh.faceGroup[f]) == 0) {
      continue;
    }
    for (int c = mesh.faceStart[f]; c < mesh.faceStart[f + 1]; ++c) {
      weights[static_cast<std::size_t>(mesh.faceVertices[c])] = 1.0f;
      any = true;
    }
  }
  if (!any) {
    DS_THROW(kInput, what, ": group:", names, " has no faces, so the map would be 0 everywhere");
  }
  return weights;
}

/// Vertex neighbours along polygon edges (consecutive corners), sorted, no duplicates.
std::vector<std::vector<int>> vertexNeighbours(const Mesh& mesh) {
  std::vector<std::vector<int>> neighbours(static_cast<std::size_t>(mesh.vertexCount()));
  const int faces = mesh.faceStart.empty() ? 0 : static_cast<int>(mesh.faceStart.size()) - 1;
  for (int f = 0; f < faces; ++f) {
    const int begin = mesh.faceStart[f];
    const int end = mesh.faceStart[f + 1];
    for (int c = begin; c < end; ++c) {
      const int a = mesh.faceVertices[c];
      const int b = mesh.faceVertices[c + 1 < end ? c + 1 : begin];
      if (a != b) {
        neighbours[static_cast<std::size_t>(a)].push_back(b);
        neighbours[static_cast<std::size_t>(b)].push_back(a);
      }
    }
  }
  for (auto& list : neighbours) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }
  return neighbours;
}

}  // namespace

std::vector<float> readWeightMap(const std::string& spec, const Mesh& driven,
                                 const std::string& what) {
  if (spec.rfind(kGroupPrefix, 0) == 0) {
    return groupMap(spec.substr(std::strlen(kGroupPrefix)), driven, what);
  }
  if (endsWith(spec, ".json")) {
    return readJsonMap(spec, driven.vertexCount(), what);
  }
  if (endsWith(spec, ".exr")) {
    return readExrMap(spec, driven.vertexCount(), what);
  }
  DS_THROW(kUsage, what, " '", spec,
           "' is not a weight map: use a .json array, a one-channel .exr, or group:NAME[,NAME]");
}

void writeWeightMapExr(const std::string& path, const std::vector<float>& weights, int width) {
  if (weights.empty() || width <= 0) {
    DS_THROW(kInternal, "writeWeightMapExr '", path, "': ", weights.size(), " weights, width ",
             width);
  }
  checkRange(weights, "weight map for '" + path + "'");
  const int vertexCount = static_cast<int>(weights.size());
  const std::size_t w = static_cast<std::size_t>(width);
  const std::size_t height = (weights.size() + w - 1) / w;
  exr_detail::writeExrAtomically(path, "weight-map", [&](std::ostream& stream) {
    std::vector<float> values(w * height, 0.0f);
    std::copy(weights.begin(), weights.end(), values.begin());
    std::vector<float> coverage(w * height, 0.0f);
    std::fill(coverage.begin(), coverage.begin() + vertexCount, 1.0f);
    Imf::Header header(width, static_cast<int>(height));
    header.compression() = exr_detail::toImf(ExrCompression::kZip);
    header.channels().insert(kWeightChannel, Imf::Channel(Imf::FLOAT));
    header.channels().insert(exr_detail::kCoverageChannel, Imf::Channel(Imf::FLOAT));
    header.insert(kAttrVertexCount, Imf::IntAttribute(vertexCount));
    Imf::FrameBuffer frameBuffer;
    frameBuffer.insert(kWeightChannel,
                       Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(values.data()), sizeof(float),
                                  sizeof(float) * w));
    frameBuffer.insert(exr_detail::kCoverageChannel,
                       Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(coverage.data()),
                                  sizeof(float), sizeof(float) * w));
    exr_detail::writeScanlines(path, stream, header, frameBuffer, static_cast<int>(height),
                               ZipEncoder::kLibdeflate, 1);
  });
}

std::vector<float> smoothWeightMap(const std::vector<float>& weights, const Mesh& mesh, int rings) {
  if (rings < 0 || rings > kMaxRings) {
    DS_THROW(kUsage, "weight-map falloff of ", rings, " rings is outside 0..", kMaxRings);
  }
  if (weights.size() != static_cast<std::size_t>(mesh.vertexCount())) {
    DS_THROW(kInternal, "smoothWeightMap: ", weights.size(), " weights for ", mesh.vertexCount(),
             " vertices");
  }
  if (rings == 0) {
    return weights;
  }
  const std::vector<std::vector<int>> neighbours = vertexNeighbours(mesh);
  const int count = mesh.vertexCount();
  std::vector<float> out(weights.size());
  // Breadth-first search to `rings` edges from each vertex; `seen` holds the search it was
  // last reached in, so it is never cleared.
  std::vector<int> seen(weights.size(), -1);
  std::vector<int> frontier;
  std::vector<int> next;
  for (int v = 0; v < count; ++v) {
    const float own = weights[static_cast<std::size_t>(v)];
    double sum = static_cast<double>(rings + 1) * own;
    double total = static_cast<double>(rings + 1);
    bool uniform = true;
    seen[static_cast<std::size_t>(v)] = v;
    frontier.assign(1, v);
    for (int d = 1; d <= rings && !frontier.empty(); ++d) {
      next.clear();
      const double kernel = static_cast<double>(rings + 1 - d);
      for (int u : frontier) {
        for (int n : neighbours[static_cast<std::size_t>(u)]) {
          if (seen[static_cast<std::size_t>(n)] == v) {
            continue;
          }
          seen[static_cast<std::size_t>(n)] = v;
          next.push_back(n);
          const float value = weights[static_cast<std::size_t>(n)];
          uniform = uniform && value == own;
          sum += kernel * value;
          total += kernel;
        }
      }
      frontier.swap(next);
    }
    out[static_cast<std::size_t>(v)] =
        uniform ? own : static_cast<float>(std::clamp(sum / total, 0.0, 1.0));
  }
  return out;
}

}  // namespace drivenshape
