// SPDX-License-Identifier: Apache-2.0
// Writes one position map with the library and dumps the exact arrays it wrote, for the Python
// check (check_posmap_exr.py) that reads the EXR back with the OpenEXR bindings.
//
//   posmap_sample MESH.obj CACHE FRAME WxH PADDING OUT.exr [rgba|legacy]
//
// writes OUT.exr (P, A, N as FLOAT, ZIP; channels named as the last argument says, default
// rgba) and, as raw little-endian float32 in texel order (row 0 = top): OUT.exr.P.raw
// (W*H*3), OUT.exr.A.raw (W*H), OUT.exr.N.raw (W*H*3).

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/position_map.h>
#include <drivenshape/position_map_backend.h>
#include <drivenshape/position_map_tables.h>

namespace {

void dump(const std::string& path, const std::vector<float>& values) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(values.data()),
            static_cast<std::streamsize>(values.size() * sizeof(float)));
  if (!out) {
    throw drivenshape::Error(drivenshape::ErrorCode::kOutput, "cannot write " + path);
  }
}

}  // namespace

int main(int argc, char** argv) {
  using namespace drivenshape;
  if (argc != 7 && argc != 8) {
    std::fprintf(stderr,
                 "usage: posmap_sample MESH.obj CACHE FRAME WxH PADDING OUT.exr [rgba|legacy]\n");
    return 2;
  }
  try {
    const Mesh mesh = readObj(argv[1]);
    const auto cache = openPointCache(argv[2]);
    const int frame = std::stoi(argv[3]);
    const auto [width, height] = parsePositionMapResolution(argv[4]);
    const PositionMapTables tables =
        buildPositionMapTables(mesh, width, height, std::stoi(argv[5]), argv[1]);
    std::vector<float> xyz(3 * static_cast<std::size_t>(cache->vertexCount()));
    cache->readFrame(frame, xyz.data());
    auto host = makeHostPositionMaps();
    host->upload(tables);
    std::vector<float> positions(3 * tables.texelCount());
    std::vector<float> normals(3 * tables.texelCount());
    host->evaluate(1, xyz.data(), positions.data(), normals.data());

    PositionMapFrameHeader header;
    header.frame = frame;
    header.topologyHash = tables.topologyHash;
    header.meshVertexCount = tables.vertexCount;
    header.padding = tables.padding;
    header.bounds = computeBounds(xyz.data(), tables.vertexCount);
    header.channels = argc == 8 ? parsePositionMapChannels(argv[7], "naming") : header.channels;
    const std::string out = argv[6];
    writePositionMapExr(out, width, height, positions.data(), tables.coverage.data(),
                        normals.data(), header);
    dump(out + ".P.raw", positions);
    dump(out + ".A.raw", tables.coverage);
    dump(out + ".N.raw", normals);
    return 0;
  } catch (const Error& error) {
    std::fprintf(stderr, "posmap_sample: %s\n", error.what());
    return static_cast<int>(error.code());
  }
}
