// SPDX-License-Identifier: Apache-2.0
// Database file: one self-describing, versioned binary file.
//
//   offset 0   8 bytes   magic "DSHAPEDB"
//          8   uint32    format version (little-endian)
//         12   uint32    0 (reserved)
//         16   uint64    header length H
//         24   H bytes   JSON header: settings, picks, meshes, block table with checksums
//     24 + H   padding to a multiple of 16, then the blocks, each 16-byte aligned
//
// Every block is raw little-endian float32 or int32 data; the header lists its name, dtype,
// shape, byte offset (from the start of the file) and FNV-1a 64 checksum. The header's
// "file_fnv1a64" is the FNV-1a 64 of the whole file with its own 16 hex digits read as '0's
// (files written before it have none and load as before; a wrong one is refused).

#include <drivenshape/database.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
#include <string_view>

#include <drivenshape/binding.h>
#include <drivenshape/error.h>
#include <drivenshape/version.h>

#include "atomic_file.h"
#include "finite.h"
#include "hash.h"

#include "json_text.h"

namespace drivenshape {
namespace {

using nlohmann::json;

constexpr char kMagic[8] = {'D', 'S', 'H', 'A', 'P', 'E', 'D', 'B'};
constexpr std::size_t kPrefixBytes = 24;
constexpr std::size_t kAlign = 16;
/// Headers are metadata (picks, the block table, settings): far below this, even with a
/// million shapes. A larger length is damage, refused before anything is allocated for it.
constexpr std::uint64_t kMaxHeaderBytes = std::uint64_t{1} << 28;
/// The header key of the whole file's checksum, and its value while the file is laid out.
constexpr const char* kFileChecksumKey = "file_fnv1a64";
constexpr const char* kChecksumPlaceholder = "0000000000000000";

struct BlockData {
  std::string name;
  std::string dtype;  // "float32" or "int32"
  std::vector<std::int64_t> shape;
  const void* data;
  std::size_t bytes;
};

template <typename T>
BlockData block(std::string name, const std::vector<T>& values, std::vector<std::int64_t> shape) {
  static_assert(sizeof(T) == 4, "blocks hold 4-byte values");
  return BlockData{std::move(name), std::is_same_v<T, float> ? "float32" : "int32",
                   std::move(shape), values.data(), values.size() * sizeof(T)};
}

std::vector<float> flatUvs(const Mesh& mesh) {
  std::vector<float> flat;
  flat.reserve(mesh.uvs.size() * 2);
  for (const auto& uv : mesh.uvs) {
    flat.push_back(uv.x());
    flat.push_back(uv.y());
  }
  return flat;
}

std::vector<float> flatPositions(const Mesh& mesh) {
  return std::vector<float>(mesh.positions.data(), mesh.positions.data() + mesh.positions.size());
}

json meshJson(const Mesh& mesh) {
  return json{{"vertices", mesh.vertexCount()},
              {"faces", mesh.faceCount()},
              {"triangles", mesh.triangleCount()},
              {"uvs", mesh.uvs.size()},
              {"topology_hash", hashToHex(topologyHash(mesh))},
              {"groups", mesh.groupNames}};
}

bool isLittleEndian() {
  const std::uint16_t probe = 1;
  unsigned char first;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

}  // namespace

const char* pickReasonName(PickReason reason) {
  switch (reason) {
    case PickReason::kSeed:
      return "seed";
    case PickReason::kFarthest:
      return "farthest";
    case PickReason::kAdded:
      return "added";
  }
  return "unknown";
}

std::uint64_t Database::contentHash() const {
  Hasher hasher;
  hasher.addValue(topologyHash(driverMesh)).addValue(topologyHash(drivenMesh));
  hasher.add(frames.data(), frames.size() * sizeof(int));
  hasher.add(driverShapes.data(), driverShapes.size() * sizeof(float));
  hasher.add(drivenShapes.data(), drivenShapes.size() * sizeof(float));
  if (!poseModel.empty()) {
    // Only databases with a model hash it: those without keep their 0.1 hash.
    const PoseModel& m = poseModel;
    hasher.add(m.partOf.data(), m.partOf.size() * sizeof(int));
    hasher.add(m.parent.data(), m.parent.size() * sizeof(int));
    hasher.add(m.up.data(), sizeof(m.up));
    hasher.addValue(m.velocityLag).addValue(m.historyFrames);
    hasher.addValue(m.lengthScale).addValue(m.linearWeight).addValue(m.ridge);
    hasher.addValue(m.errorBias).addValue(m.errorScale);
    if (m.verdictLevel > 0.0) {
      // Only models with a calibrated verdict (0.2.0 on) hash it: older ones keep their hash.
      hasher.addValue(m.verdictLevel).addValue(m.verdictMargin);
    }
    hasher.add(m.frames.data(), m.frames.size() * sizeof(int));
    hasher.add(m.features.data(), m.features.size() * sizeof(float));
    hasher.add(m.coefficients.data(), m.coefficients.size() * sizeof(float));
    hasher.add(m.basis.data(), m.basis.size() * sizeof(float));
    if (m.siblingWeight > 0.0) {
      // Only models with sibling features hash their weight: the others keep their hash.
      hasher.addValue(m.siblingWeight);
    }
    if (m.clipMixtureWeight > 0.0) {
      // Only models with per-clip models hash them: the others keep their hash.
      hasher.addValue(m.clipMixtureWeight);
      hasher.add(m.clipSizes.data(), m.clipSizes.size() * sizeof(int));
      hasher.add(m.clipCoefficients.data(), m.clipCoefficients.size() * sizeof(float));
    }
  }
  return hasher.value();
}

namespace {

/// The arrays a database file holds that the Database does not store flat: rest positions,
/// UVs and the side table, kept alive while the blocks point into them.
struct FlatDatabaseArrays {
  explicit FlatDatabaseArrays(const Database& db)
      : driverRest(flatPositions(db.driverMesh)),
        drivenRest(flatPositions(db.drivenMesh)),
        driverUv(flatUvs(db.driverMesh)),
        drivenUv(flatUvs(db.drivenMesh)),
        sides(db.drivenSides.begin(), db.drivenSides.end()) {}
  std::vector<float> driverRest;
  std::vector<float> drivenRest;
  std::vector<float> driverUv;
  std::vector<float> drivenUv;
  std::vector<int> sides;
};

/// The blocks of the file, in file order: shapes, both meshes, the side table and the pose
/// model when there are.
std::vector<BlockData> databaseBlocks(const Database& db, const FlatDatabaseArrays& flat) {
  const std::int64_t k = db.shapeCount();
  const std::int64_t vp = db.driverVertexCount();
  const std::int64_t vd = db.drivenVertexCount();
  const Mesh& dm = db.driverMesh;
  const Mesh& cm = db.drivenMesh;
  std::vector<BlockData> blocks = {
      block("driver_shapes", db.driverShapes, {k, vp, 3}),
      block("driven_shapes", db.drivenShapes, {k, vd, 3}),
      block("driver_rest", flat.driverRest, {vp, 3}),
      block("driver_face_start", dm.faceStart, {static_cast<std::int64_t>(dm.faceStart.size())}),
      block("driver_face_vertices", dm.faceVertices,
            {static_cast<std::int64_t>(dm.faceVertices.size())}),
      block("driver_face_uvs", dm.faceUvs, {static_cast<std::int64_t>(dm.faceUvs.size())}),
      block("driver_face_group", dm.faceGroup, {static_cast<std::int64_t>(dm.faceGroup.size())}),
      block("driver_uvs", flat.driverUv, {static_cast<std::int64_t>(dm.uvs.size()), 2}),
      block("driven_rest", flat.drivenRest, {vd, 3}),
      block("driven_face_start", cm.faceStart, {static_cast<std::int64_t>(cm.faceStart.size())}),
      block("driven_face_vertices", cm.faceVertices,
            {static_cast<std::int64_t>(cm.faceVertices.size())}),
      block("driven_face_uvs", cm.faceUvs, {static_cast<std::int64_t>(cm.faceUvs.size())}),
      block("driven_face_group", cm.faceGroup, {static_cast<std::int64_t>(cm.faceGroup.size())}),
      block("driven_uvs", flat.drivenUv, {static_cast<std::int64_t>(cm.uvs.size()), 2}),
  };
  if (!flat.sides.empty()) {
    blocks.push_back(block("driven_sides", flat.sides, {vd}));
  }
  const PoseModel& model = db.poseModel;
  if (!model.empty()) {
    const std::int64_t t = model.frameCount(), r = model.rank(), d = model.featureCount();
    blocks.push_back(block("model_part_of", model.partOf, {vp}));
    blocks.push_back(block("model_parent", model.parent, {model.partCount()}));
    blocks.push_back(block("model_frames", model.frames, {t}));
    blocks.push_back(block("model_features", model.features, {t, d}));
    blocks.push_back(block("model_coefficients", model.coefficients, {r, t}));
    blocks.push_back(block("model_basis", model.basis, {r, vd, 3}));
    if (model.clipMixtureWeight > 0.0) {
      blocks.push_back(block("model_clip_coefficients", model.clipCoefficients, {r, t}));
    }
  }
  return blocks;
}

/// The header's `pose_model` entry: the model's sizes and settings.
json poseModelJson(const PoseModel& model) {
  json out = {{"parts", model.partCount()},
              {"rank", model.rank()},
              {"frames", model.frameCount()},
              {"features", model.featureCount()},
              {"up", model.up},
              {"velocity_lag", model.velocityLag},
              {"history_frames", model.historyFrames},
              {"length_scale", model.lengthScale},
              {"linear_weight", model.linearWeight},
              {"ridge", model.ridge},
              {"error_bias", model.errorBias},
              {"error_scale", model.errorScale},
              {"cross_validation_error", model.crossValidationError},
              {"binding_error", model.bindingError},
              {"verdict_level", model.verdictLevel},
              {"verdict_margin", model.verdictMargin}};
  if (model.siblingWeight > 0.0) {
    out["sibling_weight"] = model.siblingWeight;
  }
  if (model.clipMixtureWeight > 0.0) {
    out["clip_mixture_weight"] = model.clipMixtureWeight;
    out["clip_frames"] = model.clipSizes;
  }
  return out;
}

/// The JSON header without its block table: picks, meshes, sources, settings, pose model.
json databaseHeader(const Database& db) {
  json picks = json::array();
  for (int i = 0; i < db.shapeCount(); ++i) {
    picks.push_back({{"frame", db.frames[i]},
                     {"reason", pickReasonName(db.reasons[i])},
                     {"distance", db.pickDistances[i]}});
  }
  json header{
      {"format", "drivenshape-database"},
      {"format_version", Database::kFormatVersion},
      {"tool_version", db.toolVersion.empty() ? std::string(kVersion) : db.toolVersion},
      {"created", db.created},
      {"content_hash", hashToHex(db.contentHash())},
      {kFileChecksumKey, kChecksumPlaceholder},
      {"shape_count", db.shapeCount()},
      {"picks", picks},
      {"driver", meshJson(db.driverMesh)},
      {"driven", meshJson(db.drivenMesh)},
      {"sources", {{"driver", db.driverSource}, {"driven", db.drivenSource}}},
      {"settings",
       {{"count", db.options.count},
        {"candidate_frames", db.options.frames},
        {"add_frames", db.options.addFrames},
        {"remove_frames", db.options.removeFrames},
        {"duplicate_tolerance", db.options.duplicateTolerance}}},
  };
  if (!db.extraClips.empty()) {
    json clips = json::array();
    for (const ReferenceClipSource& clip : db.extraClips) {
      clips.push_back({{"driver", clip.driverSource},
                       {"driven", clip.drivenSource},
                       {"frames", clip.frames},
                       {"frame_offset", clip.frameOffset}});
    }
    header["sources"]["extra_clips"] = clips;
  }
  if (!db.poseModel.empty()) {
    header["pose_model"] = poseModelJson(db.poseModel);
  }
  return header;
}

/// Adds the block table to `header` and sets each block's offset; returns the header's text.
/// Offsets depend on the header length, which depends on the offsets' digits: lay out with
/// a fixed-width placeholder pass until stable.
std::string layOutBlocks(json& header, const std::vector<BlockData>& blocks,
                         std::vector<std::size_t>& offsets) {
  offsets.assign(blocks.size(), 0);
  std::string headerText;
  for (int pass = 0; pass < 4; ++pass) {
    json table = json::array();
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      table.push_back(
          {{"name", blocks[i].name},
           {"dtype", blocks[i].dtype},
           {"shape", blocks[i].shape},
           {"offset", offsets[i]},
           {"bytes", blocks[i].bytes},
           {"fnv1a64", hashToHex(Hasher().add(blocks[i].data, blocks[i].bytes).value())}});
    }
    header["blocks"] = table;
    headerText = drivenshape::jsonText(header, 1);
    std::size_t cursor = (kPrefixBytes + headerText.size() + kAlign - 1) / kAlign * kAlign;
    bool changed = false;
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      changed = changed || offsets[i] != cursor;
      offsets[i] = cursor;
      cursor += (blocks[i].bytes + kAlign - 1) / kAlign * kAlign;
    }
    if (!changed) {
      break;
    }
  }
  return headerText;
}

/// The whole file: prefix, header, then each block at its offset.
std::string databaseFileBytes(const std::string& headerText, const std::vector<BlockData>& blocks,
                              const std::vector<std::size_t>& offsets) {
  std::string bytes;
  bytes.append(kMagic, sizeof(kMagic));
  const std::uint32_t version = Database::kFormatVersion;
  const std::uint32_t reserved = 0;
  const std::uint64_t headerLength = headerText.size();
  bytes.append(reinterpret_cast<const char*>(&version), 4);
  bytes.append(reinterpret_cast<const char*>(&reserved), 4);
  bytes.append(reinterpret_cast<const char*>(&headerLength), 8);
  bytes += headerText;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    bytes.resize(offsets[i], '\0');
    bytes.append(static_cast<const char*>(blocks[i].data), blocks[i].bytes);
  }
  return bytes;
}

/// Where the 16 hex digits of the header's file checksum start in `bytes` (a database whose
/// header is `headerLength` bytes), or npos when the header has no such key, or has it more
/// than once, or its value is not 16 characters in quotes.
std::size_t fileChecksumDigits(const std::string& bytes, std::size_t headerLength) {
  const std::string_view header = std::string_view(bytes).substr(kPrefixBytes, headerLength);
  const std::string key = std::string("\"") + kFileChecksumKey + "\"";
  const std::size_t at = header.find(key);
  if (at == std::string_view::npos || header.find(key, at + 1) != std::string_view::npos) {
    return std::string::npos;
  }
  std::size_t i = at + key.size();
  const auto skipSpace = [&]() {
    while (i < header.size() && std::strchr(" \t\r\n", header[i]) != nullptr) {
      ++i;
    }
  };
  skipSpace();
  if (i >= header.size() || header[i] != ':') {
    return std::string::npos;
  }
  ++i;
  skipSpace();
  if (i + 18 > header.size() || header[i] != '"' || header[i + 17] != '"') {
    return std::string::npos;
  }
  return kPrefixBytes + i + 1;
}

/// FNV-1a 64 of `bytes` with the 16 characters at `digits` read as '0's.
std::uint64_t fileChecksum(const std::string& bytes, std::size_t digits) {
  Hasher hasher;
  hasher.add(bytes.data(), digits).add(kChecksumPlaceholder, 16);
  hasher.add(bytes.data() + digits + 16, bytes.size() - digits - 16);
  return hasher.value();
}

}  // namespace

void saveDatabase(const std::string& path, const Database& db) {
  if (!isLittleEndian()) {
    DS_THROW(kInternal, "database files are little-endian; big-endian hosts are not supported");
  }
  const FlatDatabaseArrays flat(db);
  const std::vector<BlockData> blocks = databaseBlocks(db, flat);
  json header = databaseHeader(db);
  std::vector<std::size_t> offsets;
  const std::string headerText = layOutBlocks(header, blocks, offsets);
  std::string bytes = databaseFileBytes(headerText, blocks, offsets);
  const std::size_t digits = fileChecksumDigits(bytes, headerText.size());
  if (digits == std::string::npos) {
    DS_THROW(kInternal, "saveDatabase: the header's ", kFileChecksumKey, " was not laid out");
  }
  bytes.replace(digits, 16, hashToHex(fileChecksum(bytes, digits)));
  writeFileAtomically(path, bytes);
}

bool isDatabaseFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return false;  // a FIFO would block the read; a folder is not a database
  }
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  return in.read(magic, 8) && std::memcmp(magic, kMagic, 8) == 0;
}

namespace {

class BlockReader {
 public:
  BlockReader(std::string path, std::string bytes, const json& table)
      : mPath(std::move(path)), mBytes(std::move(bytes)) {
    for (const auto& entry : table) {
      mTable[entry.at("name").get<std::string>()] = entry;
    }
  }

  template <typename T>
  std::vector<T> read(const std::string& name, std::size_t expectedCount) const {
    const auto it = mTable.find(name);
    if (it == mTable.end()) {
      DS_THROW(kInput, mPath, ": database block '", name,
               "' is missing; the file is damaged or from an incompatible tool");
    }
    const json& entry = it->second;
    const std::string dtype = entry.at("dtype").get<std::string>();
    const std::string wanted = std::is_same_v<T, float> ? "float32" : "int32";
    const std::size_t offset = sizeAt(entry, "offset", name);
    const std::size_t bytes = sizeAt(entry, "bytes", name);
    if (dtype != wanted || bytes != expectedCount * sizeof(T)) {
      DS_THROW(kInput, mPath, ": database block '", name, "' holds ", bytes, " bytes of ", dtype,
               ", expected ", expectedCount * sizeof(T), " bytes of ", wanted);
    }
    if (offset > mBytes.size() || bytes > mBytes.size() - offset) {
      DS_THROW(kInput, mPath, ": database block '", name, "' runs past the end of the file (",
               mBytes.size(), " bytes); the file is truncated, copy or rebuild it");
    }
    checkShape(entry, name, expectedCount);
    const std::string expected = entry.at("fnv1a64").get<std::string>();
    const std::string actual = hashToHex(Hasher().add(mBytes.data() + offset, bytes).value());
    if (expected != actual) {
      DS_THROW(kInput, mPath, ": database block '", name, "' fails its checksum (", actual,
               " != ", expected,
               "); the file is corrupted, rebuild it with `drivenshape db build`");
    }
    std::vector<T> values(expectedCount);
    if (bytes > 0) {
      std::memcpy(values.data(), mBytes.data() + offset, bytes);
    }
    return values;
  }

  std::size_t count(const std::string& name) const {
    const auto it = mTable.find(name);
    if (it == mTable.end()) {
      return 0;
    }
    return sizeAt(it->second, "bytes", name) / 4;
  }

 private:
  /// A byte count or offset of the block table: a whole number (read() checks it against the
  /// file's size).
  std::size_t sizeAt(const json& entry, const char* key, const std::string& name) const {
    const json& value = entry.at(key);
    if (!value.is_number_unsigned()) {
      DS_THROW(kInput, mPath, ": database block '", name, "' has ", key, " ", jsonText(value),
               "; the file is corrupt");
    }
    return static_cast<std::size_t>(value.get<std::uint64_t>());
  }

  /// Refuses a block whose header shape (when it has one: every file so far) does not hold
  /// `count` values.
  void checkShape(const json& entry, const std::string& name, std::size_t count) const {
    if (!entry.contains("shape")) {
      return;
    }
    const json& shape = entry.at("shape");
    double values = 1;
    bool whole = shape.is_array();
    for (const json& extent : shape) {
      whole = whole && extent.is_number_unsigned();
      values *= whole ? static_cast<double>(extent.get<std::uint64_t>()) : 0.0;
    }
    if (!whole || values != static_cast<double>(count)) {
      DS_THROW(kInput, mPath, ": database block '", name, "' has shape ", jsonText(shape),
               " but holds ", count, " values; the file is corrupt, rebuild it");
    }
  }

  std::string mPath;
  std::string mBytes;
  std::map<std::string, json> mTable;
};

void readMesh(const BlockReader& blocks, const std::string& prefix, const json& info,
              const std::string& path, Mesh& mesh) {
  const std::string where = path + ": " + prefix + " mesh";
  // Counts are bounded so that every product below fits; the blocks must then match them.
  const int vertices =
      jsonInt(info.at("vertices"), where + " vertex count", 1, std::numeric_limits<int>::max() / 3);
  const int faces =
      jsonInt(info.at("faces"), where + " face count", 0, std::numeric_limits<int>::max() - 1);
  const std::vector<float> rest = blocks.read<float>(prefix + "_rest", std::size_t(vertices) * 3);
  mesh.positions = Eigen::Map<const Positions>(rest.data(), vertices, 3);
  mesh.faceStart = blocks.read<int>(prefix + "_face_start", std::size_t(faces) + 1);
  mesh.faceVertices =
      blocks.read<int>(prefix + "_face_vertices", blocks.count(prefix + "_face_vertices"));
  mesh.faceUvs = blocks.read<int>(prefix + "_face_uvs", blocks.count(prefix + "_face_uvs"));
  mesh.faceGroup = blocks.read<int>(prefix + "_face_group", std::size_t(faces));
  const std::vector<float> uv = blocks.read<float>(prefix + "_uvs", blocks.count(prefix + "_uvs"));
  mesh.uvs.resize(uv.size() / 2);
  for (std::size_t i = 0; i < mesh.uvs.size(); ++i) {
    mesh.uvs[i] = Eigen::Vector2f(uv[2 * i], uv[2 * i + 1]);
  }
  mesh.groupNames = info.at("groups").get<std::vector<std::string>>();
  validateMesh(mesh, where);
  mesh.triangulate();
  const std::string expectedHash = info.at("topology_hash").get<std::string>();
  if (hashToHex(topologyHash(mesh)) != expectedHash) {
    DS_THROW(kInput, path, ": ", prefix, " topology hash ", hashToHex(topologyHash(mesh)),
             " does not match the header's ", expectedHash, "; the file is corrupted");
  }
}

/// The pose model's header entry and blocks; Error(kInput) when they do not fit the meshes.
void readPoseModel(const BlockReader& blocks, const json& info, const std::string& path,
                   Database& db) {
  PoseModel& m = db.poseModel;
  const std::string where = path + ": pose_model";
  const int parts = jsonInt(info.at("parts"), where + ".parts", 1, 1 << 16);
  const int rank = jsonInt(info.at("rank"), where + ".rank", 1, 1 << 16);
  const int frames = jsonInt(info.at("frames"), where + ".frames", 1, 1 << 20);
  const int features = jsonInt(info.at("features"), where + ".features", 1, 1 << 16);
  m.up = info.at("up").get<std::array<double, 3>>();
  m.velocityLag = jsonInt(info.at("velocity_lag"), where + ".velocity_lag", 0, 1000);
  m.historyFrames = jsonInt(info.at("history_frames"), where + ".history_frames", 0, 1000);
  m.lengthScale = info.at("length_scale").get<double>();
  m.linearWeight = info.at("linear_weight").get<double>();
  m.ridge = info.at("ridge").get<double>();
  m.errorBias = info.at("error_bias").get<double>();
  m.errorScale = info.at("error_scale").get<double>();
  m.crossValidationError = info.at("cross_validation_error").get<double>();
  m.bindingError = info.at("binding_error").get<double>();
  // Written since 0.2.0; a model without them bounds by its predicted error (margin 0).
  m.verdictLevel = info.contains("verdict_level") ? info.at("verdict_level").get<double>() : 0.0;
  m.verdictMargin = info.contains("verdict_margin") ? info.at("verdict_margin").get<double>() : 0.0;
  // Written since 0.2.0 by a build with sibling features (a rig with parts of one parent).
  m.siblingWeight = info.contains("sibling_weight") ? info.at("sibling_weight").get<double>() : 0.0;
  m.partOf = blocks.read<int>("model_part_of", static_cast<std::size_t>(db.driverVertexCount()));
  m.parent = blocks.read<int>("model_parent", static_cast<std::size_t>(parts));
  m.frames = blocks.read<int>("model_frames", static_cast<std::size_t>(frames));
  m.features = blocks.read<float>("model_features", std::size_t(frames) * features);
  m.coefficients = blocks.read<float>("model_coefficients", std::size_t(rank) * frames);
  m.basis = blocks.read<float>("model_basis", std::size_t(rank) * db.drivenVertexCount() * 3);
  // Written since 0.2.0 by a build whose per-clip models were kept.
  if (info.contains("clip_mixture_weight")) {
    m.clipMixtureWeight = info.at("clip_mixture_weight").get<double>();
    m.clipSizes = info.at("clip_frames").get<std::vector<int>>();
    const bool sizes =
        m.clipSizes.size() >= 2 && *std::min_element(m.clipSizes.begin(), m.clipSizes.end()) >= 1 &&
        std::accumulate(m.clipSizes.begin(), m.clipSizes.end(), std::int64_t{0}) == frames;
    if (!(std::isfinite(m.clipMixtureWeight) && m.clipMixtureWeight > 0.0) || !sizes) {
      DS_THROW(kInput, where,
               ": the per-clip models' weight or frames (clip_mixture_weight, clip_frames) do "
               "not fit its ",
               frames, " frames; the file is corrupt, rebuild it");
    }
    m.clipCoefficients = blocks.read<float>("model_clip_coefficients", std::size_t(rank) * frames);
  }
  for (int p : m.partOf) {
    if (p < 0 || p >= parts) {
      DS_THROW(kInput, where, ": a driver vertex names part ", p, " of ", parts,
               "; the file is corrupt, rebuild it");
    }
  }
  for (int p = 0; p < parts; ++p) {
    if (m.parent[p] < -1 || m.parent[p] >= parts || m.parent[p] == p) {
      DS_THROW(kInput, where, ": part ", p, " has parent ", m.parent[p],
               "; the file is corrupt, rebuild it");
    }
  }
  for (int p = 0; p < parts; ++p) {
    int up = p;
    for (int step = 0; step <= parts && up >= 0; ++step) {
      up = m.parent[static_cast<std::size_t>(up)];
    }
    if (up >= 0) {
      DS_THROW(kInput, where, ": part ", p,
               " is its own ancestor (a cycle of parents); the file is corrupt, rebuild it");
    }
  }
  if (info.contains("sibling_weight") &&
      !(std::isfinite(m.siblingWeight) && m.siblingWeight > 0.0 && !m.siblingPairs().empty())) {
    DS_THROW(kInput, where, ": sibling_weight ", m.siblingWeight,
             " is not a positive weight of parts with a common parent; the file is corrupt, "
             "rebuild it");
  }
  const bool finite = std::isfinite(m.lengthScale) && m.lengthScale > 0 &&
                      std::isfinite(m.linearWeight) && std::isfinite(m.ridge) && m.ridge > 0 &&
                      std::isfinite(m.errorBias) && std::isfinite(m.errorScale) &&
                      m.verdictLevel >= 0.0 && m.verdictLevel < 1.0 &&
                      std::isfinite(m.verdictMargin) && m.verdictMargin >= 0.0;
  if (!finite || m.featureCount() != features) {
    DS_THROW(kInput, where, ": the kernel settings or the feature count (", features,
             ") do not fit the parts; the file is corrupt, rebuild it");
  }
}

}  // namespace

namespace {

/// Checks the 24-byte prefix (magic, format version, header length) against the file's size
/// before anything of the size the header claims is allocated, then reads the file.
std::string readDatabaseBytes(const std::string& path, std::uint64_t& headerLength) {
  requireRegularFile(path, "database");
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  char prefix[kPrefixBytes] = {};
  std::ifstream in(path, std::ios::binary);
  if (ec || !in.read(prefix, kPrefixBytes) || std::memcmp(prefix, kMagic, 8) != 0) {
    DS_THROW(kInput, "'", path, "' is not a drivenshape database (no DSHAPEDB magic); build one ",
             "with `drivenshape db build`");
  }
  std::uint32_t version;
  std::memcpy(&version, prefix + 8, 4);
  std::memcpy(&headerLength, prefix + 16, 8);
  if (version != static_cast<std::uint32_t>(Database::kFormatVersion)) {
    DS_THROW(kInput, "'", path, "' is a database of format version ", version,
             "; this drivenshape (", kVersion, ") reads version ", Database::kFormatVersion,
             version > static_cast<std::uint32_t>(Database::kFormatVersion)
                 ? ": upgrade drivenshape"
                 : ": rebuild the database with this version");
  }
  if (headerLength > size - kPrefixBytes) {
    DS_THROW(kInput, "'", path, "' is truncated (header of ", headerLength,
             " bytes does not fit in the file of ", size, " bytes)");
  }
  if (headerLength > kMaxHeaderBytes) {
    DS_THROW(kInput, "'", path, "' declares a header of ", headerLength, " bytes; a database ",
             "header has at most ", kMaxHeaderBytes, " bytes, the file is corrupt");
  }
  in.close();
  std::string bytes = readWholeFile(path, "database");
  if (bytes.size() < kPrefixBytes || headerLength > bytes.size() - kPrefixBytes) {
    DS_THROW(kInput, "'", path, "' changed while it was read (", bytes.size(), " bytes)");
  }
  return bytes;
}

/// Refuses a file whose header's whole-file checksum is malformed or does not match. A file
/// without one (written before the checksum was added) is read as before.
void checkFileChecksum(const std::string& path, const std::string& bytes,
                       std::uint64_t headerLength, const json& header) {
  if (!header.is_object() || !header.contains(kFileChecksumKey)) {
    return;
  }
  // A short file is said to be truncated (as without a checksum), not merely corrupted.
  if (header.contains("blocks") && header.at("blocks").is_array()) {
    for (const json& entry : header.at("blocks")) {
      const json* offset =
          entry.is_object() && entry.contains("offset") ? &entry.at("offset") : nullptr;
      const json* size =
          entry.is_object() && entry.contains("bytes") ? &entry.at("bytes") : nullptr;
      if (offset != nullptr && size != nullptr && offset->is_number_unsigned() &&
          size->is_number_unsigned() &&
          (offset->get<std::uint64_t>() > bytes.size() ||
           size->get<std::uint64_t>() > bytes.size() - offset->get<std::uint64_t>())) {
        DS_THROW(kInput, "'", path, "' is truncated (", bytes.size(),
                 " bytes; its blocks run past the end); copy or rebuild it");
      }
    }
  }
  const json& stored = header.at(kFileChecksumKey);
  std::uint64_t expected = 0;
  const std::size_t digits = fileChecksumDigits(bytes, headerLength);
  if (!stored.is_string() || !hexToHash(stored.get<std::string>(), expected) ||
      digits == std::string::npos || bytes.compare(digits, 16, stored.get<std::string>()) != 0) {
    DS_THROW(kInput, "'", path, "': the header's ", kFileChecksumKey, " ", jsonText(stored),
             " is not one checksum of 16 hex digits; the file is corrupt, rebuild it");
  }
  const std::uint64_t actual = fileChecksum(bytes, digits);
  if (actual != expected) {
    DS_THROW(kInput, "'", path, "' fails its checksum (", hashToHex(actual),
             " != ", stored.get<std::string>(),
             "); the file is corrupted or was edited, rebuild it with `drivenshape db build`");
  }
}

/// Throws Error(kInput) naming the block and the value when `values` hold a NaN or infinity.
void requireFiniteBlock(const std::string& path, const char* block,
                        const std::vector<float>& values) {
  const std::size_t bad = firstNonFinite(values.data(), values.size());
  if (bad < values.size()) {
    DS_THROW(kInput, "'", path, "': block '", block, "' value ", bad,
             " is not a finite number; the file is corrupt, rebuild it");
  }
}

/// What the blocks' checksums cannot see (a file edited and its checksums recomputed, or a
/// block that never was valid): non-finite shapes or model values, and a content that
/// differs from the header's content hash.
void checkLoadedDatabase(const Database& db, const json& header, const std::string& path) {
  requireFiniteBlock(path, "driver_shapes", db.driverShapes);
  requireFiniteBlock(path, "driven_shapes", db.drivenShapes);
  const PoseModel& m = db.poseModel;
  if (!m.empty()) {
    requireFiniteBlock(path, "model_features", m.features);
    requireFiniteBlock(path, "model_coefficients", m.coefficients);
    requireFiniteBlock(path, "model_basis", m.basis);
    requireFiniteBlock(path, "model_clip_coefficients", m.clipCoefficients);
  }
  const json& stored = header.at("content_hash");
  const std::string actual = hashToHex(db.contentHash());
  if (!stored.is_string() || stored.get<std::string>() != actual) {
    DS_THROW(kInput, "'", path, "': its content hashes to ", actual, ", not to the header's ",
             jsonText(stored),
             "; the database was changed after it was built, rebuild it with `drivenshape db "
             "build`");
  }
}

}  // namespace

Database loadDatabase(const std::string& path) {
  std::uint64_t headerLength = 0;
  std::string bytes = readDatabaseBytes(path, headerLength);
  const json header = parseJsonText(std::string_view(bytes).substr(kPrefixBytes, headerLength),
                                    "'" + path + "': database header");
  checkFileChecksum(path, bytes, headerLength, header);
  Database db;
  try {
    const BlockReader blocks(path, std::move(bytes), header.at("blocks"));
    readMesh(blocks, "driver", header.at("driver"), path, db.driverMesh);
    readMesh(blocks, "driven", header.at("driven"), path, db.drivenMesh);
    const int k = jsonInt(header.at("shape_count"), path + ": shape_count", 1, 1 << 20);
    for (const auto& pick : header.at("picks")) {
      db.frames.push_back(jsonInt(pick.at("frame"), path + ": a pick's frame"));
      const std::string reason = pick.at("reason").get<std::string>();
      db.reasons.push_back(reason == "seed"    ? PickReason::kSeed
                           : reason == "added" ? PickReason::kAdded
                                               : PickReason::kFarthest);
      db.pickDistances.push_back(pick.at("distance").get<double>());
    }
    if (static_cast<int>(db.frames.size()) != k || k < 1) {
      DS_THROW(kInput, "'", path, "': header lists ", db.frames.size(), " picks for ", k,
               " shapes");
    }
    db.driverShapes =
        blocks.read<float>("driver_shapes", std::size_t(k) * db.driverVertexCount() * 3);
    db.drivenShapes =
        blocks.read<float>("driven_shapes", std::size_t(k) * db.drivenVertexCount() * 3);
    const json& settings = header.at("settings");
    db.options.count = jsonInt(settings.at("count"), path + ": settings.count");
    const auto frameList = [&](const char* key) {
      std::vector<int> frames;
      for (const json& frame : settings.at(key)) {
        frames.push_back(jsonInt(frame, path + ": settings." + key));
      }
      return frames;
    };
    db.options.frames = frameList("candidate_frames");
    db.options.addFrames = frameList("add_frames");
    db.options.removeFrames = frameList("remove_frames");
    db.options.duplicateTolerance = settings.at("duplicate_tolerance").get<double>();
    db.driverSource = header.at("sources").at("driver").get<std::string>();
    db.drivenSource = header.at("sources").at("driven").get<std::string>();
    if (header.at("sources").contains("extra_clips")) {
      // Provenance only (the model's frames carry the offsets): read, never trusted.
      for (const json& clip : header.at("sources").at("extra_clips")) {
        ReferenceClipSource source;
        source.driverSource = clip.at("driver").get<std::string>();
        source.drivenSource = clip.at("driven").get<std::string>();
        for (const json& frame : clip.at("frames")) {
          source.frames.push_back(jsonInt(frame, path + ": sources.extra_clips frame"));
        }
        source.frameOffset =
            jsonInt(clip.at("frame_offset"), path + ": sources.extra_clips offset");
        db.extraClips.push_back(std::move(source));
      }
    }
    db.toolVersion = header.at("tool_version").get<std::string>();
    db.created = header.at("created").get<std::string>();
    if (header.contains("pose_model")) {
      readPoseModel(blocks, header.at("pose_model"), path, db);
    }
    if (blocks.count("driven_sides") > 0) {
      const std::vector<int> sides =
          blocks.read<int>("driven_sides", static_cast<std::size_t>(db.drivenVertexCount()));
      for (std::size_t v = 0; v < sides.size(); ++v) {
        if (sides[v] != kSideInside && sides[v] != kSideOutside) {
          DS_THROW(kInput, "'", path, "': block 'driven_sides' gives driven vertex ", v,
                   " the side ", sides[v],
                   " (1 outside or -1 inside); the file is corrupt, rebuild it");
        }
      }
      db.drivenSides.assign(sides.begin(), sides.end());
    }
    checkLoadedDatabase(db, header, path);
  } catch (const json::exception& error) {
    DS_THROW(kInput, "'", path, "': database header is incomplete (", error.what(),
             "); the file is damaged or from an incompatible tool");
  }
  return db;
}

}  // namespace drivenshape
