// SPDX-License-Identifier: Apache-2.0
// Database reader (src/database/database.cpp): loadDatabase on the input as it is, then (when its
// header parses) on the input with every block checksum and the whole file's checksum
// recomputed, so that mutated block data gets past the checksum tests to the code that trusts
// it (the content hash, which only a loaded database can compute, still stops most). A database
// that loads is checked (meshes, shape blocks, the bake's driver mesh check) and must survive
// saveDatabase and loadDatabase unchanged.

#include <cstring>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include <drivenshape/binding.h>
#include <drivenshape/database.h>
#include <drivenshape/mesh_check.h>

#include "hash.h"

#include "fuzz_support.h"

namespace ds = drivenshape;

namespace {

/// `bytes` with every block's fnv1a64 checksum in the header recomputed, so that mutations of
/// block data reach the code behind the checksum test. Nothing when the header is not JSON with
/// a block table, when every checksum already matches, or when the rewritten (one-line) header
/// would not fit where the old one was.
std::optional<std::string> withRepairedChecksums(const std::string& bytes) {
  constexpr std::size_t kPrefixBytes = 24;  // magic, version, reserved, header length
  if (bytes.size() < kPrefixBytes) {
    return std::nullopt;
  }
  std::uint64_t headerLength = 0;
  std::memcpy(&headerLength, bytes.data() + 16, 8);
  if (headerLength > bytes.size() - kPrefixBytes) {
    return std::nullopt;
  }
  // No exceptions (allow_exceptions = false): a header this cannot read is left as it is.
  nlohmann::json header = nlohmann::json::parse(
      bytes.begin() + kPrefixBytes,
      bytes.begin() + kPrefixBytes + static_cast<std::ptrdiff_t>(headerLength), nullptr, false);
  if (header.is_discarded() || !header.is_object() || !header.contains("blocks") ||
      !header["blocks"].is_array()) {
    return std::nullopt;
  }
  bool changed = false;
  for (nlohmann::json& entry : header["blocks"]) {
    if (!entry.is_object() || !entry.contains("offset") || !entry.contains("bytes") ||
        !entry["offset"].is_number_unsigned() || !entry["bytes"].is_number_unsigned()) {
      continue;
    }
    const auto offset = entry["offset"].get<std::uint64_t>();
    const auto size = entry["bytes"].get<std::uint64_t>();
    if (offset > bytes.size() || size > bytes.size() - offset) {
      continue;
    }
    const std::string sum = ds::hashToHex(ds::Hasher().add(bytes.data() + offset, size).value());
    if (!entry.contains("fnv1a64") || entry["fnv1a64"] != sum) {
      entry["fnv1a64"] = sum;
      changed = true;
    }
  }
  if (!changed) {
    return std::nullopt;
  }
  const std::string text = header.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (text.size() > headerLength) {
    return std::nullopt;
  }
  // Blocks sit at absolute offsets: a shorter header leaves ignored bytes before them.
  std::string repaired = bytes;
  const std::uint64_t newLength = text.size();
  std::memcpy(repaired.data() + 16, &newLength, 8);
  repaired.replace(kPrefixBytes, text.size(), text);
  // The whole file's checksum (its own 16 digits read as '0's), when the header has one.
  const std::string key = "\"file_fnv1a64\":\"";
  const std::size_t at = text.find(key);
  if (at != std::string::npos && at + key.size() + 16 <= text.size()) {
    const std::size_t digits = kPrefixBytes + at + key.size();
    repaired.replace(digits, 16, std::string(16, '0'));
    repaired.replace(digits, 16,
                     ds::hashToHex(ds::Hasher().add(repaired.data(), repaired.size()).value()));
  }
  return repaired;
}

void loadAndCheck(const std::string& path) {
  ds::Database db;
  if (!ds::fuzz::expectOnlyErrors("loadDatabase", [&] { db = ds::loadDatabase(path); })) {
    return;
  }
  ds::fuzz::checkMesh(db.driverMesh, "loadDatabase(driver mesh)");
  ds::fuzz::checkMesh(db.drivenMesh, "loadDatabase(driven mesh)");
  // What `bake` does first with a database: check its driver mesh (an Error or a warning).
  ds::fuzz::expectOnlyErrors("checkDriverMesh(database driver)", [&] {
    ds::checkDriverMesh(db.driverMesh, path, ds::DriverMeshUse::kBake, true);
  });
  const std::size_t k = static_cast<std::size_t>(db.shapeCount());
  ds::fuzz::require(k >= 1 && db.reasons.size() == k && db.pickDistances.size() == k &&
                        db.driverShapes.size() == k * 3 * db.driverVertexCount() &&
                        db.drivenShapes.size() == k * 3 * db.drivenVertexCount(),
                    "loadDatabase", "picks and shape blocks disagree with the shape count");
  ds::fuzz::require(db.drivenSides.empty() ||
                        db.drivenSides.size() == static_cast<std::size_t>(db.drivenVertexCount()),
                    "loadDatabase", "the side table disagrees with the driven vertex count");
  for (std::int8_t side : db.drivenSides) {
    ds::fuzz::require(side == ds::kSideInside || side == ds::kSideOutside, "loadDatabase",
                      "a driven vertex's side is neither inside nor outside");
  }
  const std::uint64_t hash = db.contentHash();
  const std::string again = ds::fuzz::scratchPath("again.dsdb");
  ds::fuzz::expectSuccess("saveDatabase(loaded)", [&] { ds::saveDatabase(again, db); });
  ds::Database reloaded;
  ds::fuzz::expectSuccess("loadDatabase(saved)", [&] { reloaded = ds::loadDatabase(again); });
  ds::fuzz::require(reloaded.contentHash() == hash && reloaded.frames == db.frames &&
                        reloaded.drivenMesh.groupNames == db.drivenMesh.groupNames &&
                        reloaded.drivenSides == db.drivenSides,
                    "saveDatabase/loadDatabase", "a loaded database changed when saved again");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  loadAndCheck(ds::fuzz::writeInput("input.dsdb", bytes));
  if (const auto repaired = withRepairedChecksums(bytes)) {
    loadAndCheck(ds::fuzz::writeInput("repaired.dsdb", *repaired));
  }
  return 0;
}
