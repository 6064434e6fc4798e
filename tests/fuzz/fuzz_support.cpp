// SPDX-License-Identifier: Apache-2.0
#include "fuzz_support.h"

#include <cxxabi.h>
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>

namespace drivenshape::fuzz {
namespace {

[[noreturn]] void environmentFailure(const std::string& what) {
  std::fprintf(stderr, "drivenshape fuzz: %s\n", what.c_str());
  std::abort();
}

std::string& ownedFolder() {
  static std::string folder;
  return folder;
}

void removeOwnedFolder() {
  std::error_code ec;
  std::filesystem::remove_all(ownedFolder(), ec);
}

/// The scratch folder: $DRIVENSHAPE_FUZZ_TMPDIR (made and removed by run_fuzz.sh), else one
/// per process in /dev/shm (memory: no disk traffic per execution), else in the temp folder.
const std::string& scratchFolder() {
  static const std::string folder = [] {
    if (const char* given = std::getenv("DRIVENSHAPE_FUZZ_TMPDIR"); given != nullptr && *given) {
      std::error_code ec;
      std::filesystem::create_directories(given, ec);
      return std::string(given);
    }
    std::error_code ec;
    std::filesystem::path base = "/dev/shm";
    if (!std::filesystem::is_directory(base, ec) || ::access(base.c_str(), W_OK) != 0) {
      base = std::filesystem::temp_directory_path(ec);
    }
    const std::filesystem::path mine =
        base / ("drivenshape-fuzz-" + std::to_string(static_cast<long>(::getpid())));
    std::filesystem::create_directories(mine, ec);
    if (ec) {
      environmentFailure("cannot create the scratch folder " + mine.string() + ": " + ec.message());
    }
    ownedFolder() = mine.string();
    std::atexit(removeOwnedFolder);
    return mine.string();
  }();
  return folder;
}

/// A 4 x 3 grid of vertices (3 x 2 quads) at height `lift`; the quads of column c are in group c.
Mesh gridMesh(float lift, const char* const groups[3], bool withUvs) {
  constexpr int kColumns = 4;  // vertices per row
  constexpr int kRows = 3;
  Mesh mesh;
  mesh.positions.resize(kColumns * kRows, 3);
  for (int row = 0; row < kRows; ++row) {
    for (int column = 0; column < kColumns; ++column) {
      const int v = row * kColumns + column;
      mesh.positions.row(v) << 0.1f * static_cast<float>(column), 0.1f * static_cast<float>(row),
          lift;
      if (withUvs) {
        mesh.uvs.emplace_back(static_cast<float>(column) / (kColumns - 1),
                              static_cast<float>(row) / (kRows - 1));
      }
    }
  }
  mesh.groupNames = {groups[0], groups[1], groups[2]};
  mesh.faceStart = {0};
  for (int column = 0; column + 1 < kColumns; ++column) {  // group = column of quads
    for (int row = 0; row + 1 < kRows; ++row) {
      const int corner = row * kColumns + column;
      for (int v : {corner, corner + 1, corner + kColumns + 1, corner + kColumns}) {
        mesh.faceVertices.push_back(v);
        if (withUvs) {
          mesh.faceUvs.push_back(v);
        }
      }
      mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
      mesh.faceGroup.push_back(column);
    }
  }
  mesh.triangulate();
  return mesh;
}

}  // namespace

std::string scratchPath(const std::string& name) {
  return scratchFolder() + "/" + name;
}

std::string writeInput(const std::string& name, const std::uint8_t* data, std::size_t size) {
  std::string path = scratchPath(name);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) {
    environmentFailure("cannot create " + path + ": " + std::strerror(errno));
  }
  std::size_t done = 0;
  while (done < size) {
    const ssize_t wrote = ::write(fd, data + done, size - done);
    if (wrote < 0 && errno == EINTR) {
      continue;
    }
    if (wrote <= 0) {
      environmentFailure("cannot write " + path + ": " + std::strerror(errno));
    }
    done += static_cast<std::size_t>(wrote);
  }
  ::close(fd);
  return path;
}

std::string writeInput(const std::string& name, const std::string& bytes) {
  return writeInput(name, reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
}

void reportFinding(const char* reader, const char* type, const std::string& what,
                   bool errorAllowed) {
  int status = 0;
  std::unique_ptr<char, void (*)(void*)> readable(
      abi::__cxa_demangle(type, nullptr, nullptr, &status), std::free);
  std::fprintf(stderr, "\n==drivenshape-fuzz== FINDING in %s: %s escaped%s: %s\n", reader,
               status == 0 && readable ? readable.get() : type,
               errorAllowed ? " (only drivenshape::Error may)" : " (this call must succeed)",
               what.c_str());
  std::fflush(stderr);
  std::abort();
}

void require(bool condition, const char* reader, const std::string& what) {
  if (!condition) {
    std::fprintf(stderr, "\n==drivenshape-fuzz== FINDING in %s: %s\n", reader, what.c_str());
    std::fflush(stderr);
    std::abort();
  }
}

void checkMesh(const Mesh& mesh, const char* reader) {
  const std::int64_t vertices = mesh.vertexCount();
  const std::int64_t faces = mesh.faceCount();
  const std::int64_t corners = static_cast<std::int64_t>(mesh.faceVertices.size());
  require(mesh.positions.rows() >= 0 && mesh.positions.cols() == 3, reader, "positions not V x 3");
  require(static_cast<std::int64_t>(mesh.faceStart.size()) == faces + 1, reader,
          "faceStart holds " + std::to_string(mesh.faceStart.size()) + " offsets for " +
              std::to_string(faces) + " faces");
  require(mesh.faceStart.front() == 0, reader, "faceStart[0] is not 0");
  require(mesh.faceStart.back() == corners, reader,
          "faceStart ends at " + std::to_string(mesh.faceStart.back()) + ", not at the " +
              std::to_string(corners) + " face corners");
  std::int64_t triangles = 0;
  for (std::int64_t f = 0; f < faces; ++f) {
    const std::int64_t size = static_cast<std::int64_t>(mesh.faceStart[f + 1]) - mesh.faceStart[f];
    require(size >= 3, reader,
            "face " + std::to_string(f) + " has " + std::to_string(size) + " corners");
    triangles += size - 2;
    require(mesh.faceGroup[f] >= 0 &&
                mesh.faceGroup[f] < static_cast<std::int64_t>(mesh.groupNames.size()),
            reader,
            "face " + std::to_string(f) + " has group id " + std::to_string(mesh.faceGroup[f]));
  }
  for (std::int64_t c = 0; c < corners; ++c) {
    const int v = mesh.faceVertices[c];
    require(v >= 0 && v < vertices, reader,
            "face corner " + std::to_string(c) + " references vertex " + std::to_string(v) +
                " of " + std::to_string(vertices));
  }
  require(mesh.faceUvs.empty() || static_cast<std::int64_t>(mesh.faceUvs.size()) == corners, reader,
          "faceUvs is neither empty nor parallel to faceVertices");
  for (const int t : mesh.faceUvs) {
    require(t >= -1 && t < static_cast<std::int64_t>(mesh.uvs.size()), reader,
            "face corner references UV " + std::to_string(t) + " of " +
                std::to_string(mesh.uvs.size()));
  }
  require(mesh.triangleCount() == triangles &&
              static_cast<std::int64_t>(mesh.triangleFace.size()) == triangles,
          reader, "triangles are not the fan triangulation of the faces");
  for (int t = 0; t < mesh.triangleCount(); ++t) {
    const int f = mesh.triangleFace[static_cast<std::size_t>(t)];
    require(f >= 0 && f < faces, reader, "triangleFace out of range");
    for (int k = 0; k < 3; ++k) {
      require(mesh.triangles(t, k) >= 0 && mesh.triangles(t, k) < vertices, reader,
              "triangle vertex out of range");
    }
  }
  volatile std::uint64_t sink = topologyHash(mesh);
  (void)sink;
}

const Mesh& fixedDriver() {
  static const char* const kGroups[3] = {"left_leg", "pelvis", "right_leg"};
  static const Mesh mesh = gridMesh(0.0f, kGroups, false);
  return mesh;
}

const Mesh& fixedDriven() {
  static const char* const kGroups[3] = {"left_trouser", "waist", "right_trouser"};
  static const Mesh mesh = gridMesh(0.01f, kGroups, true);
  return mesh;
}

}  // namespace drivenshape::fuzz
