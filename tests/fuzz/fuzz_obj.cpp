// SPDX-License-Identifier: Apache-2.0
// OBJ reader (src/io/obj.cpp): readObj, the fan triangulation and the topology hash of what it
// returns, then the mesh written into a database and read back (group names and faces reach the
// database's JSON header, as in `drivenshape db build`).

#include <drivenshape/database.h>
#include <drivenshape/mesh.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ds::fuzz::writeInput("input.obj", data, size);
  ds::Mesh mesh;
  if (!ds::fuzz::expectOnlyErrors("readObj", [&] { mesh = ds::readObj(path); })) {
    return 0;
  }
  ds::fuzz::checkMesh(mesh, "readObj");
  ds::computeBounds(mesh.positions.data(), mesh.vertexCount());

  ds::Database db;
  db.driverMesh = mesh;
  db.drivenMesh = mesh;
  db.frames = {1};
  db.reasons = {ds::PickReason::kSeed};
  db.pickDistances = {0.0};
  db.driverShapes.assign(mesh.positions.data(), mesh.positions.data() + mesh.positions.size());
  db.drivenShapes = db.driverShapes;
  // The tool must read back what it wrote: an Error here is a finding as well.
  const std::string dbPath = ds::fuzz::scratchPath("obj.dsdb");
  ds::fuzz::expectSuccess("saveDatabase(mesh from readObj)", [&] { ds::saveDatabase(dbPath, db); });
  ds::Database loaded;
  ds::fuzz::expectSuccess("loadDatabase(saved from readObj)",
                          [&] { loaded = ds::loadDatabase(dbPath); });
  ds::fuzz::require(ds::topologyHash(loaded.drivenMesh) == ds::topologyHash(mesh) &&
                        loaded.drivenMesh.groupNames.size() == mesh.groupNames.size() &&
                        loaded.contentHash() == db.contentHash(),
                    "saveDatabase/loadDatabase", "a mesh read from OBJ did not survive a database");
  return 0;
}
