// SPDX-License-Identifier: Apache-2.0
// PNG previews of position maps: 8-bit RGB, P scaled from the frame's bounds to colours.
// A minimal PNG encoder (IHDR, one IDAT of zlib-compressed unfiltered rows, IEND).

#include <drivenshape/position_map.h>

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <drivenshape/error.h>

#include "atomic_file.h"

namespace drivenshape {
namespace {

void appendBigEndian(std::string& out, std::uint32_t value) {
  out.push_back(static_cast<char>((value >> 24) & 0xffu));
  out.push_back(static_cast<char>((value >> 16) & 0xffu));
  out.push_back(static_cast<char>((value >> 8) & 0xffu));
  out.push_back(static_cast<char>(value & 0xffu));
}

/// length, type, data, CRC-32 of type + data.
void appendChunk(std::string& out, const char* type, const std::string& data) {
  appendBigEndian(out, static_cast<std::uint32_t>(data.size()));
  const std::string body = std::string(type, 4) + data;
  out += body;
  const uLong crc = crc32(crc32(0L, Z_NULL, 0), reinterpret_cast<const Bytef*>(body.data()),
                          static_cast<uInt>(body.size()));
  appendBigEndian(out, static_cast<std::uint32_t>(crc));
}

/// A PNG file of `rows` (each: filter byte 0, then width RGB triples).
std::string encodePng(int width, int height, const std::vector<unsigned char>& rows) {
  std::string png("\x89PNG\r\n\x1a\n", 8);
  std::string header;
  appendBigEndian(header, static_cast<std::uint32_t>(width));
  appendBigEndian(header, static_cast<std::uint32_t>(height));
  header +=
      std::string("\x08\x02\x00\x00\x00", 5);  // 8 bits, RGB, deflate, no filter, no interlace
  appendChunk(png, "IHDR", header);

  uLongf packedSize = compressBound(static_cast<uLong>(rows.size()));
  std::string packed(packedSize, '\0');
  const int status = compress2(reinterpret_cast<Bytef*>(packed.data()), &packedSize, rows.data(),
                               static_cast<uLong>(rows.size()), Z_BEST_SPEED);
  if (status != Z_OK) {
    DS_THROW(kInternal, "zlib compress2 failed with status ", status, " on a PNG preview");
  }
  packed.resize(packedSize);
  appendChunk(png, "IDAT", packed);
  appendChunk(png, "IEND", "");
  return png;
}

unsigned char toByte(float value, float lo, float hi, float scale) {
  const float range = hi - lo;
  const float t = range > 0.0f ? (value - lo) / range : 0.5f;
  const float clamped = std::min(1.0f, std::max(0.0f, t));
  return static_cast<unsigned char>(std::lround(clamped * scale * 255.0f));
}

}  // namespace

std::string positionMapPreviewPath(const std::string& exrPath) {
  const auto slash = exrPath.find_last_of('/');
  const auto dot = exrPath.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) {
    return exrPath + ".png";
  }
  return exrPath.substr(0, dot) + ".png";
}

PositionMapPreview::PositionMapPreview(int width, int height, const Bounds& bounds)
    : mWidth(width), mHeight(height), mBounds(bounds) {
  if (width < 1 || height < 1) {
    DS_THROW(kInternal, "a position-map preview of ", width, "x", height, " texels");
  }
  const std::size_t rowBytes = 1 + 3 * static_cast<std::size_t>(width);
  mRows.assign(rowBytes * static_cast<std::size_t>(height), 0);
}

void PositionMapPreview::draw(const PositionMapTables& band, int firstRow, const float* positions) {
  if (positions == nullptr || band.width != mWidth || firstRow < 0 ||
      firstRow + band.height > mHeight) {
    DS_THROW(kInternal, "PositionMapPreview: no band of rows ", firstRow, "-",
             firstRow + band.height - 1, " to draw");
  }
  const std::size_t width = static_cast<std::size_t>(mWidth);
  const std::size_t rowBytes = 1 + 3 * width;
  for (std::size_t e = 0; e < band.texels.size(); ++e) {
    const std::size_t texel = static_cast<std::size_t>(band.texels[e]);
    const bool covered = band.texelSources[e] == static_cast<int>(e);
    const float scale = covered ? 1.0f : 0.5f;
    const std::size_t row = static_cast<std::size_t>(firstRow) + texel / width;
    unsigned char* pixel = mRows.data() + row * rowBytes + 1 + 3 * (texel % width);
    for (int k = 0; k < 3; ++k) {
      pixel[k] = toByte(positions[3 * texel + static_cast<std::size_t>(k)], mBounds.min[k],
                        mBounds.max[k], scale);
    }
  }
}

void PositionMapPreview::write(const std::string& path) const {
  writeFileAtomically(path, encodePng(mWidth, mHeight, mRows));
}

void writePositionMapPreview(const std::string& path, const PositionMapTables& tables,
                             const float* positions, const Bounds& bounds) {
  if (positions == nullptr || tables.width < 1 || tables.height < 1) {
    DS_THROW(kInternal, "writePositionMapPreview '", path, "': no map to draw");
  }
  PositionMapPreview preview(tables.width, tables.height, bounds);
  preview.draw(tables, 0, positions);
  preview.write(path);
}

}  // namespace drivenshape
