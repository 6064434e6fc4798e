// SPDX-License-Identifier: Apache-2.0
// Position-map EXR files (layout and attributes: position_map.h).

#include <drivenshape/position_map.h>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfFramesPerSecond.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstddef>
#include <exception>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/version.h>

#include "atomic_file.h"
#include "hash.h"

#include "exr_common.h"

namespace drivenshape {
namespace {

using namespace exr_detail;  // the names shared with the other EXR kind

// Header attributes of position maps only (all well under OpenEXR's 31-byte limit). The names
// shared with point-cache EXRs (dsFrame, dsTopologyHash, dsToolVersion, dsBounds*, the P, N and
// A channels) are in io/exr_common.h and mean the same thing in both.
constexpr const char* kAttrKind = "dsKind";
constexpr const char* kKindValue = "positionMap";
constexpr const char* kAttrMeshVertexCount = "dsMeshVertexCount";
constexpr const char* kAttrPadding = "dsPadding";
constexpr const char* kAttrUvLayout = "dsUvLayout";
constexpr const char* kUvLayoutValue =
    "texel (x,y) centre = (u,v) = ((x+0.5)/W, 1-(y+0.5)/H); row 0 is v = 1 (top)";

/// The channel names of one naming. kRgba: the position is the default (colour) layer, so
/// OpenImageIO lists it first and shows it, Nuke reads it as rgba, and OpenEXR's Python module
/// hands out "RGBA" and "N" arrays. kLegacy: the point cache's names (io/exr_common.h).
struct ChannelNames {
  const char* const* position;  // x, y, z
  const char* coverage;
  const char* const* normal;  // x, y, z
};

constexpr const char* kRgbaPosition[3] = {"R", "G", "B"};
constexpr const char* kRgbaNormal[3] = {"N.R", "N.G", "N.B"};

ChannelNames channelNames(PositionMapChannels channels) {
  if (channels == PositionMapChannels::kLegacy) {
    return {kPositionChannels, kCoverageChannel, kNormalChannels};
  }
  return {kRgbaPosition, kCoverageChannel, kRgbaNormal};
}

bool hasAll(const Imf::ChannelList& list, const char* const names[3]) {
  return std::all_of(names, names + 3,
                     [&](const char* name) { return list.findChannel(name) != nullptr; });
}

}  // namespace

const char* positionMapChannelsName(PositionMapChannels channels) {
  return channels == PositionMapChannels::kLegacy ? "legacy" : "rgba";
}

PositionMapChannels parsePositionMapChannels(const std::string& text, const std::string& flag) {
  std::string lower = text;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  for (PositionMapChannels channels : {PositionMapChannels::kRgba, PositionMapChannels::kLegacy}) {
    if (lower == positionMapChannelsName(channels)) {
      return channels;
    }
  }
  DS_THROW(kUsage, flag, " '", text,
           "' is not a channel naming; use rgba (R G B, A, N.R N.G N.B) or legacy (P.X P.Y P.Z, "
           "A, N.X N.Y N.Z)");
}

std::vector<std::string> positionMapChannelNames(PositionMapChannels channels, bool normals) {
  const ChannelNames names = channelNames(channels);
  std::vector<std::string> out(names.position, names.position + 3);
  out.emplace_back(names.coverage);
  if (normals) {
    out.insert(out.end(), names.normal, names.normal + 3);
  }
  return out;
}

namespace {

/// The EXR header of a position map (layout and attributes: position_map.h).
Imf::Header exrHeaderOf(int width, int height, bool normals, const PositionMapFrameHeader& header) {
  const ChannelNames names = channelNames(header.channels);
  Imf::Header exrHeader(width, height);
  exrHeader.compression() = toImf(header.compression);
  for (int k = 0; k < 3; ++k) {
    exrHeader.channels().insert(names.position[k], Imf::Channel(Imf::FLOAT));
  }
  exrHeader.channels().insert(names.coverage, Imf::Channel(Imf::FLOAT));
  if (normals) {
    const Imf::PixelType type = header.halfNormals ? Imf::HALF : Imf::FLOAT;
    for (int k = 0; k < 3; ++k) {
      exrHeader.channels().insert(names.normal[k], Imf::Channel(type));
    }
  }
  exrHeader.insert(kAttrKind, Imf::StringAttribute(kKindValue));
  exrHeader.insert(kAttrFrame, Imf::IntAttribute(header.frame));
  exrHeader.insert(kAttrTopologyHash, Imf::StringAttribute(hashToHex(header.topologyHash)));
  exrHeader.insert(kAttrToolVersion, Imf::StringAttribute(kVersion));
  exrHeader.insert(kAttrMeshVertexCount, Imf::IntAttribute(header.meshVertexCount));
  const Bounds& b = header.bounds;
  exrHeader.insert(kAttrBoundsMin, Imf::V3fAttribute(Imath::V3f(b.min.x(), b.min.y(), b.min.z())));
  exrHeader.insert(kAttrBoundsMax, Imf::V3fAttribute(Imath::V3f(b.max.x(), b.max.y(), b.max.z())));
  exrHeader.insert(kAttrPadding, Imf::IntAttribute(header.padding));
  exrHeader.insert(kAttrUvLayout, Imf::StringAttribute(kUvLayoutValue));
  Imf::addFramesPerSecond(exrHeader, Imf::guessExactFps(header.framesPerSecond));
  return exrHeader;
}

/// `data` moved back by `rows` rows of `rowBytes`: the base of a slice addressed by absolute y
/// whose first row in memory is row `rows` (OpenEXR's way of reading a band).
char* rowsBack(const void* data, int rows, std::size_t rowBytes) {
  return const_cast<char*>(static_cast<const char*>(data)) -
         static_cast<std::ptrdiff_t>(rows) * static_cast<std::ptrdiff_t>(rowBytes);
}

}  // namespace

/// A position-map file being written: its temporary file, header and scan-line writer.
struct PositionMapExrWriter::State {
  std::string path;
  int width = 0;
  int height = 0;
  bool normals = false;
  PositionMapFrameHeader header;
  AtomicFile file;
  Imf::Header exrHeader;
  std::unique_ptr<ScanlineWriter> writer;
  int nextRow = 0;
  std::vector<half> halfNormals;  ///< one band's normals rounded (OpenEXR does not convert)

  State(const std::string& finalPath, int w, int h, bool withNormals,
        const PositionMapFrameHeader& frameHeader)
      : path(finalPath),
        width(w),
        height(h),
        normals(withNormals),
        header(frameHeader),
        file(finalPath),
        exrHeader(exrHeaderOf(w, h, withNormals, frameHeader)) {}

  /// The slices of a band of `rows` rows from nextRow.
  Imf::FrameBuffer band(int rows, const float* positions, const float* coverage,
                        const float* normalValues) {
    const ChannelNames names = channelNames(header.channels);
    const std::size_t rowTexels = static_cast<std::size_t>(width);
    Imf::FrameBuffer frameBuffer;
    insertXyzSlices(
        frameBuffer, names.position,
        reinterpret_cast<const float*>(rowsBack(positions, nextRow, 3 * sizeof(float) * rowTexels)),
        rowTexels);
    frameBuffer.insert(
        names.coverage,
        Imf::Slice(Imf::FLOAT, rowsBack(coverage, nextRow, sizeof(float) * rowTexels),
                   sizeof(float), sizeof(float) * rowTexels));
    if (normals && header.halfNormals) {
      const std::size_t count = 3 * rowTexels * static_cast<std::size_t>(rows);
      halfNormals.resize(count);
      for (std::size_t i = 0; i < count; ++i) {
        halfNormals[i] = half(normalValues[i]);
      }
      char* bytes = rowsBack(halfNormals.data(), nextRow, 3 * sizeof(half) * rowTexels);
      for (int k = 0; k < 3; ++k) {
        frameBuffer.insert(names.normal[k],
                           Imf::Slice(Imf::HALF, bytes + k * sizeof(half), 3 * sizeof(half),
                                      3 * sizeof(half) * rowTexels));
      }
    } else if (normals) {
      insertXyzSlices(frameBuffer, names.normal,
                      reinterpret_cast<const float*>(
                          rowsBack(normalValues, nextRow, 3 * sizeof(float) * rowTexels)),
                      rowTexels);
    }
    return frameBuffer;
  }
};

namespace {

/// Runs `step` of writing `path`; an exception other than drivenshape::Error (OpenEXR's)
/// becomes Error(kOutput) naming the file.
template <typename Step>
void writeStep(const std::string& path, Step&& step) {
  try {
    step();
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    DS_THROW(kOutput, "cannot write position-map EXR '", path, "': ", e.what());
  }
}

}  // namespace

PositionMapExrWriter::PositionMapExrWriter(const std::string& path, int width, int height,
                                           bool normals, const PositionMapFrameHeader& header) {
  if (width < 1 || height < 1 || width > kMaxPositionMapSide || height > kMaxPositionMapSide) {
    DS_THROW(kUsage, "position map size ", width, "x", height, " is outside 1..",
             kMaxPositionMapSide, " texels per side (", path, ")");
  }
  if (!(header.framesPerSecond > 0.0) || !std::isfinite(header.framesPerSecond)) {
    DS_THROW(kUsage, "frames per second ", header.framesPerSecond, " must be positive (", path,
             ")");
  }
  writeStep(path, [&] {
    mState = std::make_unique<State>(path, width, height, normals, header);
    mState->writer = std::make_unique<ScanlineWriter>(
        path, mState->file.stream(), mState->exrHeader, header.zipEncoder, header.encodeThreads);
  });
}

PositionMapExrWriter::~PositionMapExrWriter() = default;

void PositionMapExrWriter::writeRows(int rows, const float* positions, const float* coverage,
                                     const float* normals) {
  State& state = *mState;
  if (positions == nullptr || coverage == nullptr || (state.normals && normals == nullptr)) {
    DS_THROW(kInternal, "PositionMapExrWriter '", state.path, "': no positions or coverage");
  }
  if (rows < 1 || state.nextRow + rows > state.height) {
    DS_THROW(kInternal, "PositionMapExrWriter '", state.path, "': ", rows, " rows from row ",
             state.nextRow, " pass the map's ", state.height);
  }
  writeStep(state.path,
            [&] { state.writer->write(state.band(rows, positions, coverage, normals), rows); });
  state.nextRow += rows;
}

void PositionMapExrWriter::commit() {
  State& state = *mState;
  if (state.nextRow != state.height) {
    DS_THROW(kInternal, "PositionMapExrWriter '", state.path, "': committed after ", state.nextRow,
             " of ", state.height, " rows");
  }
  writeStep(state.path, [&] { state.writer->finish(); });
  state.writer.reset();
  state.file.commit();
}

void writePositionMapExr(const std::string& path, int width, int height, const float* positions,
                         const float* coverage, const float* normals,
                         const PositionMapFrameHeader& header) {
  if (positions == nullptr || coverage == nullptr) {
    DS_THROW(kInternal, "writePositionMapExr '", path, "': no positions or coverage");
  }
  PositionMapExrWriter file(path, width, height, normals != nullptr, header);
  file.writeRows(height, positions, coverage, normals);
  file.commit();
}

namespace {

/// The header of `path` if it is a position map, else nothing; Error(kInput) on a bad hash or
/// (with `requireChannels`) when neither naming's position channels are all there.
std::optional<PositionMapInfo> positionMapHeader(const std::string& path, bool requireChannels) {
  const auto file = openExr(path, "position-map");
  const Imf::Header& header = file->header();
  const auto* kind = header.findTypedAttribute<Imf::StringAttribute>(kAttrKind);
  if (kind == nullptr || kind->value() != kKindValue) {
    return std::nullopt;
  }
  const Imf::ChannelList& channels = header.channels();
  std::optional<PositionMapChannels> naming;
  for (PositionMapChannels candidate : {PositionMapChannels::kRgba, PositionMapChannels::kLegacy}) {
    if (hasAll(channels, channelNames(candidate).position)) {
      naming = candidate;
      break;
    }
  }
  if (!naming && requireChannels) {
    std::string present;
    for (auto it = channels.begin(); it != channels.end(); ++it) {
      present += std::string(present.empty() ? "" : " ") + it.name();
    }
    DS_THROW(kInput, "position-map EXR '", path,
             "': no position channels (R G B, or P.X P.Y P.Z as --channels legacy writes); "
             "it has: ",
             present.empty() ? std::string("none") : present);
  }
  PositionMapInfo info;
  static_cast<ExrSharedHeader&>(info) = readSharedHeader(path, header);
  const Imath::Box2i& window = header.dataWindow();
  info.width = window.max.x - window.min.x + 1;
  info.height = window.max.y - window.min.y + 1;
  if (const auto* count = header.findTypedAttribute<Imf::IntAttribute>(kAttrMeshVertexCount)) {
    info.meshVertexCount = count->value();
  }
  if (const auto* padding = header.findTypedAttribute<Imf::IntAttribute>(kAttrPadding)) {
    info.padding = padding->value();
  }
  if (!naming) {
    return info;  // the kind test: dsKind says what the file is meant to be
  }
  info.channels = *naming;
  const ChannelNames names = channelNames(info.channels);
  info.hasNormals = hasAll(channels, names.normal);
  if (info.hasNormals) {
    info.halfNormals = channels.findChannel(names.normal[0])->type == Imf::HALF;
  }
  return info;
}

}  // namespace

bool isPositionMapExr(const std::string& path) {
  try {
    return positionMapHeader(path, false).has_value();
  } catch (const std::exception&) {
    return false;
  }
}

PositionMapInfo readPositionMapExrInfo(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    DS_THROW(kInput, "position-map EXR '", path, "' does not exist");
  }
  std::optional<PositionMapInfo> info;
  try {
    info = positionMapHeader(path, true);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    DS_THROW(kInput, "cannot read EXR '", path, "': ", e.what());
  }
  if (!info) {
    DS_THROW(kInput, path, ": not a drivenshape position map (no ", kAttrKind, " '", kKindValue,
             "' attribute); `drivenshape info` describes point caches too");
  }
  return *info;
}

}  // namespace drivenshape
