// SPDX-License-Identifier: Apache-2.0
// What every fuzz target shares: the input written to a file (the readers take paths), the
// policy for exceptions, fixed meshes for the JSON inputs, and checks of the Mesh invariants.
//
// The policy: for bad input a reader throws drivenshape::Error, and that is the expected outcome.
// Any other exception that leaves a reader (nlohmann::json, std::out_of_range, std::bad_alloc,
// std::filesystem, OpenEXR's Iex) is a finding: it is printed and the process aborts, so
// libFuzzer keeps the input as a crash.

#pragma once

#include <cstddef>
#include <cstdint>
#include <exception>
#include <string>
#include <typeinfo>

#include <drivenshape/error.h>
#include <drivenshape/mesh.h>

namespace drivenshape::fuzz {

/// Writes `size` bytes to `name` (e.g. "input.obj": the extension matters to some readers) in
/// this process's scratch folder and returns the file's path. The folder is
/// $DRIVENSHAPE_FUZZ_TMPDIR when set, else a new folder under /dev/shm (or the temp folder),
/// removed at a normal exit (a crash leaves its few KB behind; run_fuzz.sh cleans up).
std::string writeInput(const std::string& name, const std::uint8_t* data, std::size_t size);
/// The same for text (JSON written by a target, a second file).
std::string writeInput(const std::string& name, const std::string& bytes);
/// The path `name` would have in the scratch folder.
std::string scratchPath(const std::string& name);

/// Prints "<reader>: <what>" with the exception's type and aborts (a libFuzzer crash).
/// `errorAllowed`: whether drivenshape::Error would have been fine (it is said in the message).
[[noreturn]] void reportFinding(const char* reader, const char* type, const std::string& what,
                                bool errorAllowed = true);

/// Runs `body`. drivenshape::Error is the expected outcome for bad input; any other exception
/// escaping is reported and aborts. Returns true when `body` returned normally.
template <typename Body>
bool expectOnlyErrors(const char* reader, Body&& body) {
  try {
    body();
    return true;
  } catch (const Error&) {
    return false;
  } catch (const std::exception& e) {
    reportFinding(reader, typeid(e).name(), e.what());
  } catch (...) {
    reportFinding(reader, "unknown", "an exception that is not a std::exception");
  }
}

/// Runs `body`, which must succeed (the tool reading back what it wrote): any exception,
/// drivenshape::Error included, is reported and aborts.
template <typename Body>
void expectSuccess(const char* what, Body&& body) {
  try {
    body();
  } catch (const std::exception& e) {
    reportFinding(what, typeid(e).name(), e.what(), false);
  } catch (...) {
    reportFinding(what, "unknown", "an exception that is not a std::exception", false);
  }
}

/// Aborts with a message unless `condition`: an invariant a reader promises was broken.
void require(bool condition, const char* reader, const std::string& what);

/// Checks what Mesh documents for a mesh a reader returned: faceStart F + 1 ascending offsets
/// from 0 to faceVertices.size(), faces of at least 3 corners, vertex ids in range, UV ids in
/// range or -1 (faceUvs empty or parallel to faceVertices), group ids in range, and triangles
/// that are the fan triangulation. Touches every element (so ASan sees every access).
void checkMesh(const Mesh& mesh, const char* reader);

/// A small driver (12 vertices, 6 quads in groups "left_leg", "pelvis", "right_leg") and driven
/// mesh (12 vertices, 6 quads with UVs in groups "left_trouser", "waist", "right_trouser") for
/// the readers that resolve names and indices against meshes. The seed corpus refers to them.
const Mesh& fixedDriver();
const Mesh& fixedDriven();

}  // namespace drivenshape::fuzz
