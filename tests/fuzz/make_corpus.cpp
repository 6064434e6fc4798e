// SPDX-License-Identifier: Apache-2.0
// Writes the binary part of the fuzz seed corpus and the regression files that have to be
// computed (a database whose corrupted block carries a valid checksum, an EXR with a corrupted
// attribute size) with the project's own writers. Run by make_corpus.sh:
//
//     fuzz_make_corpus tests/fuzz
//
// writes tests/fuzz/corpus/<target>/<name> and tests/fuzz/regressions/<target>/<name>. The text
// seeds (OBJ, JSON, frame ranges) are plain files kept by hand beside them.

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <drivenshape/binding.h>
#include <drivenshape/database.h>
#include <drivenshape/layers.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/position_map.h>

#include "hash.h"

#include "fuzz_support.h"

namespace ds = drivenshape;
namespace fs = std::filesystem;

namespace {

std::string readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void writeBytes(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) {
    throw std::runtime_error("cannot write " + path.string());
  }
  std::printf("%6zu  %s\n", bytes.size(), path.string().c_str());
}

/// Runs a writer that takes a path, then stores what it wrote under `path`.
template <typename Writer>
void writeWith(const fs::path& path, Writer&& writer) {
  const fs::path scratch = fs::temp_directory_path() / ("ds-corpus-" + path.filename().string());
  writer(scratch.string());
  writeBytes(path, readBytes(scratch));
  fs::remove(scratch);
}

/// V x 3 positions of a mesh moved by `t` (a small deformation per frame or shape).
std::vector<float> moved(const ds::Mesh& mesh, float t) {
  std::vector<float> xyz(mesh.positions.data(), mesh.positions.data() + mesh.positions.size());
  for (std::size_t i = 0; i < xyz.size(); i += 3) {
    xyz[i + 2] += t * xyz[i];
  }
  return xyz;
}

void writePc2Seeds(const fs::path& dir) {
  const float xyz[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1.5f, 1, 0, 0.5f, 0, 1, 0.5f,
                       0, 0, 1, 1, 0, 1, 0, 1, 1, 0, 0, 2,    1, 0, 2,    0, 1, 2};
  writeWith(dir / "four_frames_from_1001.pc2",
            [&](const std::string& p) { ds::writePc2(p, 3, 1001.0f, 4, xyz); });
  writeWith(dir / "half_rate.pc2",
            [&](const std::string& p) { ds::writePc2(p, 3, 1.0f, 4, xyz, 0.5f); });
  writeWith(dir / "rate_2_negative_start.pc2",
            [&](const std::string& p) { ds::writePc2(p, 2, -3.0f, 3, xyz, 2.0f); });
}

void writePointCacheSeeds(const fs::path& dir) {
  const ds::Mesh& mesh = ds::fuzz::fixedDriven();
  const std::vector<float> xyz = moved(mesh, 0.25f);
  const std::vector<float> normals(xyz.size(), 0.5f);
  // zip.exr and zips.exr: OpenEXR's own deflate, as the seeds were first written; the
  // *_libdeflate seeds: the default encoder's deflate streams.
  const struct {
    const char* name;
    ds::ExrCompression compression;
    ds::ZipEncoder encoder;
  } kinds[] = {{"zip.exr", ds::ExrCompression::kZip, ds::ZipEncoder::kOpenExr},
               {"none.exr", ds::ExrCompression::kNone, ds::ZipEncoder::kOpenExr},
               {"zips.exr", ds::ExrCompression::kZips, ds::ZipEncoder::kOpenExr},
               {"piz.exr", ds::ExrCompression::kPiz, ds::ZipEncoder::kOpenExr},
               {"zip_libdeflate.exr", ds::ExrCompression::kZip, ds::ZipEncoder::kLibdeflate},
               {"zips_libdeflate.exr", ds::ExrCompression::kZips, ds::ZipEncoder::kLibdeflate}};
  for (const auto& kind : kinds) {
    ds::ExrWriteOptions options;
    options.width = 5;  // 12 vertices: 3 rows, the last one padded
    options.compression = kind.compression;
    options.zipEncoder = kind.encoder;
    options.frame = 1001;
    options.topologyHash = ds::topologyHash(mesh);
    options.syncToDisk = false;
    writeWith(dir / kind.name, [&](const std::string& p) {
      ds::writePointCacheExr(p, mesh.vertexCount(), xyz.data(), nullptr, options);
    });
  }
  ds::ExrWriteOptions options;
  options.zipEncoder = ds::ZipEncoder::kOpenExr;
  options.width = 16;
  options.frame = -3;
  options.settingsHash = 0x0123456789abcdefULL;
  options.framesPerSecond = 25.0;
  options.stringAttributes = {{"dsLayers", "mix wind"}, {"comment", "seed"}};
  options.syncToDisk = false;
  writeWith(dir / "normals_attributes_one_row.exr", [&](const std::string& p) {
    ds::writePointCacheExr(p, mesh.vertexCount(), xyz.data(), normals.data(), options);
  });
}

void writePositionMapSeeds(const fs::path& dir) {
  constexpr int kWidth = 8;
  constexpr int kHeight = 6;
  std::vector<float> positions(3 * kWidth * kHeight);
  std::vector<float> coverage(kWidth * kHeight);
  std::vector<float> normals(positions.size());
  for (int i = 0; i < kWidth * kHeight; ++i) {
    positions[3 * i] = 0.1f * static_cast<float>(i % kWidth);
    positions[3 * i + 1] = 0.1f * static_cast<float>(i / kWidth);
    coverage[i] = (i % 3 == 0) ? 0.0f : 1.0f;
    normals[3 * i + 2] = 1.0f;
  }
  const ds::Mesh& mesh = ds::fuzz::fixedDriven();
  ds::PositionMapFrameHeader header;
  header.frame = 1001;
  header.topologyHash = ds::topologyHash(mesh);
  header.meshVertexCount = mesh.vertexCount();
  header.padding = 2;
  header.bounds = ds::computeBounds(positions.data(), kWidth * kHeight);
  // The default naming (R G B, A, N.R N.G N.B) ...
  header.zipEncoder = ds::ZipEncoder::kOpenExr;  // as the seeds were first written
  writeWith(dir / "rgba_zip.exr", [&](const std::string& p) {
    ds::writePositionMapExr(p, kWidth, kHeight, positions.data(), coverage.data(), nullptr, header);
  });
  header.zipEncoder = ds::ZipEncoder::kLibdeflate;  // the default encoder's deflate streams
  writeWith(dir / "rgba_zip_libdeflate.exr", [&](const std::string& p) {
    ds::writePositionMapExr(p, kWidth, kHeight, positions.data(), coverage.data(), normals.data(),
                            header);
  });
  header.zipEncoder = ds::ZipEncoder::kOpenExr;
  header.compression = ds::ExrCompression::kPiz;
  header.halfNormals = true;
  writeWith(dir / "rgba_half_normals_piz.exr", [&](const std::string& p) {
    ds::writePositionMapExr(p, kWidth, kHeight, positions.data(), coverage.data(), normals.data(),
                            header);
  });
  // ... and the legacy one (P.X P.Y P.Z, A, N.X N.Y N.Z), which the seeds below had first.
  header.channels = ds::PositionMapChannels::kLegacy;
  header.compression = ds::ExrCompression::kZip;
  header.halfNormals = false;
  writeWith(dir / "zip.exr", [&](const std::string& p) {
    ds::writePositionMapExr(p, kWidth, kHeight, positions.data(), coverage.data(), nullptr, header);
  });
  header.compression = ds::ExrCompression::kPiz;
  header.halfNormals = true;
  writeWith(dir / "half_normals_piz.exr", [&](const std::string& p) {
    ds::writePositionMapExr(p, kWidth, kHeight, positions.data(), coverage.data(), normals.data(),
                            header);
  });
  header.compression = ds::ExrCompression::kNone;
  header.halfNormals = false;
  header.framesPerSecond = 30.0;
  writeWith(dir / "float_normals_none.exr", [&](const std::string& p) {
    ds::writePositionMapExr(p, kWidth, kHeight, positions.data(), coverage.data(), normals.data(),
                            header);
  });
}

ds::Database tinyDatabase(int shapes) {
  ds::Database db;
  db.driverMesh = ds::fuzz::fixedDriver();
  db.drivenMesh = ds::fuzz::fixedDriven();
  for (int i = 0; i < shapes; ++i) {
    db.frames.push_back(1001 + 7 * i);
    db.reasons.push_back(i == 0 ? ds::PickReason::kSeed : ds::PickReason::kFarthest);
    db.pickDistances.push_back(0.125 * i);
    const float t = 0.1f * static_cast<float>(i);
    const std::vector<float> driver = moved(db.driverMesh, t);
    const std::vector<float> driven = moved(db.drivenMesh, t);
    db.driverShapes.insert(db.driverShapes.end(), driver.begin(), driver.end());
    db.drivenShapes.insert(db.drivenShapes.end(), driven.begin(), driven.end());
  }
  db.options.count = shapes;
  db.options.frames = {1001, 1008, 1015};
  db.options.addFrames = {1001};
  db.driverSource = "driver.obj + train.driver.pc2";
  db.drivenSource = "driven.obj + train.driven.pc2";
  db.toolVersion = "fuzz-seed";
  db.created = "2024-01-01T00:00:00Z";
  return db;
}

std::string databaseBytes(const ds::Database& db) {
  std::string bytes;
  const fs::path scratch = fs::temp_directory_path() / "ds-corpus-db.dsdb";
  ds::saveDatabase(scratch.string(), db);
  bytes = readBytes(scratch);
  fs::remove(scratch);
  return bytes;
}

/// `bytes` (a database) with the int32 values of block `name` changed by `edit`, and that
/// block's checksum in the header recomputed in place (same length: the layout is unchanged).
template <typename Edit>
std::string withEditedBlock(std::string bytes, const std::string& name, Edit&& edit) {
  std::uint64_t headerLength = 0;
  std::memcpy(&headerLength, bytes.data() + 16, 8);
  const std::string headerText = bytes.substr(24, headerLength);
  const nlohmann::json header = nlohmann::json::parse(headerText);
  for (const auto& entry : header.at("blocks")) {
    if (entry.at("name") != name) {
      continue;
    }
    const auto offset = entry.at("offset").get<std::size_t>();
    const auto size = entry.at("bytes").get<std::size_t>();
    std::vector<std::int32_t> values(size / 4);
    std::memcpy(values.data(), bytes.data() + offset, size);
    edit(values);
    std::memcpy(bytes.data() + offset, values.data(), size);
    // The entry's keys are sorted (bytes, dtype, fnv1a64, name, ...): its checksum is the last
    // "fnv1a64" before its name.
    const std::string oldSum = entry.at("fnv1a64").get<std::string>();
    const std::string newSum = ds::hashToHex(ds::Hasher().add(bytes.data() + offset, size).value());
    const std::size_t namePos = bytes.find("\"name\": \"" + name + "\"", 24);
    const std::size_t sumPos = bytes.rfind("\"" + oldSum + "\"", namePos);
    if (namePos == std::string::npos || sumPos == std::string::npos || sumPos < 24) {
      throw std::runtime_error("cannot find the checksum of block " + name);
    }
    bytes.replace(sumPos + 1, oldSum.size(), newSum);
    return bytes;
  }
  throw std::runtime_error("no block " + name);
}

void writeDatabaseFiles(const fs::path& corpus, const fs::path& regressions) {
  const std::string two = databaseBytes(tinyDatabase(2));
  writeBytes(corpus / "two_shapes.dsdb", two);
  ds::Database noUvs = tinyDatabase(1);
  noUvs.drivenMesh.uvs.clear();
  noUvs.drivenMesh.faceUvs.clear();
  writeBytes(corpus / "one_shape_no_uvs.dsdb", databaseBytes(noUvs));
  // The provenance of extra reference clips (db build --also) in the header's sources.
  ds::Database clips = tinyDatabase(2);
  clips.extraClips.push_back({"more.driver.pc2", "more.driven.pc2", {1, 2, 3, 9}, 100000});
  writeBytes(corpus / "extra_clips.dsdb", databaseBytes(clips));
  // The side of the skin of every driven vertex (db build stores it): cloth and muscle.
  ds::Database sides = tinyDatabase(2);
  for (int v = 0; v < sides.drivenVertexCount(); ++v) {
    sides.drivenSides.push_back(v % 3 == 0 ? ds::kSideInside : ds::kSideOutside);
  }
  const std::string sidesBytes = databaseBytes(sides);
  writeBytes(corpus / "driven_sides.dsdb", sidesBytes);
  // A pose model (one root part, two reference frames, rank 1) with the verdict's calibration
  // (0.2.0): its header entry and blocks.
  ds::Database pose = tinyDatabase(2);
  ds::PoseModel& model = pose.poseModel;
  model.partOf.assign(static_cast<std::size_t>(pose.driverVertexCount()), 0);
  model.parent = {-1};
  model.frames = {1001, 1008};
  model.features = {0.0f, 0.0f, 0.0f, 0.01f, -0.02f, 0.0f};  // 2 frames x 3 features
  model.coefficients = {0.5f, -0.25f};                       // rank 1 x 2 frames
  model.basis.assign(static_cast<std::size_t>(pose.drivenVertexCount()) * 3, 0.001f);
  model.lengthScale = 0.5;
  model.linearWeight = 1.0;
  model.ridge = 0.1;
  model.errorBias = 0.001;
  model.errorScale = 0.02;
  model.crossValidationError = 0.004;
  model.bindingError = 0.01;
  model.verdictLevel = 0.9;
  model.verdictMargin = 0.003;
  writeBytes(corpus / "pose_model.dsdb", databaseBytes(pose));
  // The same model over three parts, two of one parent, with sibling features (db build
  // --model-siblings): 3 + 9 + 9 pose features and 9 for the pair, per frame.
  ds::Database siblings = pose;
  ds::PoseModel& three = siblings.poseModel;
  for (std::size_t v = 0; v < three.partOf.size(); ++v) {
    three.partOf[v] = static_cast<int>(v % 3);
  }
  three.parent = {-1, 0, 0};
  three.siblingWeight = 0.5;
  three.features.assign(2 * 30, 0.0f);
  three.features[3] = 0.01f;
  three.features[30 + 21] = -0.02f;
  writeBytes(corpus / "pose_model_siblings.dsdb", databaseBytes(siblings));
  // The same model with per-clip models (db build --model-per-clip): one frame per clip.
  model.clipMixtureWeight = 1.0;
  model.clipSizes = {1, 1};
  model.clipCoefficients = {0.4f, -0.2f};
  writeBytes(corpus / "pose_model_clips.dsdb", databaseBytes(pose));

  // Crash report: a face offset past the face-vertex block, checksum valid -> heap overflow in
  // Mesh::triangulate.
  writeBytes(regressions / "driven_face_start_past_face_vertices.dsdb",
             withEditedBlock(two, "driven_face_start",
                             [](std::vector<std::int32_t>& start) { start.back() += 4096; }));
  // Crash report: offsets so far apart that the triangle count overflows int.
  writeBytes(regressions / "driven_face_start_int_overflow.dsdb",
             withEditedBlock(two, "driven_face_start", [](std::vector<std::int32_t>& start) {
               start.front() = std::numeric_limits<std::int32_t>::min() + 1;
               start.back() = std::numeric_limits<std::int32_t>::max();
             }));
  // A side that is neither 1 nor -1, checksum valid: refused, naming the vertex.
  writeBytes(regressions / "driven_sides_bad_value.dsdb",
             withEditedBlock(sidesBytes, "driven_sides",
                             [](std::vector<std::int32_t>& side) { side[1] = 5; }));
}

void writeWeightMapSeeds(const fs::path& dir) {
  std::vector<float> weights(static_cast<std::size_t>(ds::fuzz::fixedDriven().vertexCount()));
  for (std::size_t i = 0; i < weights.size(); ++i) {
    weights[i] = static_cast<float>(i % 5) / 4.0f;
  }
  writeWith(dir / "weights.exr",
            [&](const std::string& p) { ds::writeWeightMapExr(p, weights, 5); });
}

/// A point-cache EXR whose dsToolVersion attribute claims 0x7fffffff bytes (OpenEXR sizes the
/// value from that field before reading it).
std::string exrWithHugeAttribute(const fs::path& seed) {
  std::string bytes = readBytes(seed);
  const std::string attribute = std::string("dsToolVersion") + '\0' + "string" + '\0';
  const std::size_t at = bytes.find(attribute);
  if (at == std::string::npos) {
    throw std::runtime_error("no dsToolVersion attribute in " + seed.string());
  }
  const unsigned char size[4] = {0xff, 0xff, 0xff, 0x7f};
  bytes.replace(at + attribute.size(), 4, reinterpret_cast<const char*>(size), 4);
  return bytes;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s FUZZ_FOLDER (tests/fuzz)\n", argv[0]);
    return 2;
  }
  try {
    const fs::path root = argv[1];
    const fs::path corpus = root / "corpus";
    const fs::path regressions = root / "regressions";
    writePc2Seeds(corpus / "pc2");
    writePointCacheSeeds(corpus / "point_cache_exr");
    writePositionMapSeeds(corpus / "position_map_exr");
    writeDatabaseFiles(corpus / "database", regressions / "database");
    writeWeightMapSeeds(corpus / "weight_map");
    const std::string hugeAttribute = exrWithHugeAttribute(corpus / "point_cache_exr" / "zip.exr");
    for (const char* target : {"point_cache_exr", "position_map_exr", "weight_map"}) {
      writeBytes(regressions / target / "attribute_size_2gib.exr", hugeAttribute);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz_make_corpus: %s\n", e.what());
    return 1;
  }
  return 0;
}
