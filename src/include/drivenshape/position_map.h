// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

namespace drivenshape {

// ---------------------------------------------------------------------------------------
// Position maps: UV-space images of a deforming mesh for compositing. Each texel whose centre
// lies in a UV triangle holds the world position interpolated from that triangle's vertices.
//
// UV-to-image convention. OBJ v points up, image rows go down; row 0 is the TOP of the image
// (v = 1), which is also the first scanline of the EXR. Texel (x, y) of a W x H map covers
//
//     u in [x / W, (x + 1) / W]      v in [1 - (y + 1) / H, 1 - y / H]
//
// and is sampled at its centre (u, v) = ((x + 0.5) / W, 1 - (y + 0.5) / H):
//
//     v = 1  +-------+-------+-- ... --+-------+   row 0       (first EXR scanline)
//            | (0,0) | (1,0) |         |(W-1,0)|
//            +-------+-------+-- ... --+-------+   row 1
//            | (0,1) |   .   |         |       |
//            :       :       :         :       :
//            +-------+-------+-- ... --+-------+   row H-1     (last EXR scanline)
//            |(0,H-1)|       |         |       |
//     v = 0  +-------+-------+-- ... --+-------+
//          u = 0                             u = 1
//
// A UV triangle in the top-left corner of the UV square lands on the left end of row 0.
//
// UVs outside [0, 1] are refused (Error(kInput) naming the face and the UV): a map covers the
// 0-1 tile only, and wrapping or clamping would silently pile islands onto each other.
//
// Coverage is decided exactly: UVs are snapped to 1/256 texel and tested against texel
// centres in integer arithmetic, with a fixed tie rule for centres that lie on an edge or a
// vertex (like a GPU's top-left rule), so triangles that share an edge never both claim a
// texel and never leave a gap between them. The barycentric weights of a covered texel are
// computed in double from the unsnapped UVs.
// Where UV islands overlap, the triangle with the lowest index (fan order of the faces, see
// Mesh::triangulate) keeps the texel, and the overlap is reported (UvOverlapReport).
//
// Padding dilates every island by N texels so that filtering across a UV seam does not pull
// in background. A texel within chessboard distance N (max(|dx|, |dy|), i.e. N rings of the
// 8-neighbourhood) of a covered texel copies the values of its nearest covered texel: the one
// at the smallest chessboard distance, then the smallest Euclidean distance, then the lowest
// row-major index. Padded texels carry P (and N) but A = 0: A is 1 exactly on covered texels,
// so a compositor can matte with it while the padding keeps filtered lookups clean.

/// Largest width or height accepted for a map (a 16384^2 map holds 3 GiB of P: PositionMapWriter
/// writes one that large a band of rows at a time).
inline constexpr int kMaxPositionMapSide = 16384;
/// Largest padding accepted, in texels (the dilation costs time in its square).
inline constexpr int kMaxPositionMapPadding = 256;

/// Parses a resolution `W` (square) or `WxH`. Throws Error(kUsage) naming `flag` and the text
/// when it is malformed or a side is outside 1..kMaxPositionMapSide.
std::pair<int, int> parsePositionMapResolution(const std::string& text,
                                               const std::string& flag = "--res");

/// UV texels claimed by more than one triangle (islands overlapping in UV space).
struct UvOverlapReport {
  long long texels = 0;     ///< texels inside two or more UV triangles
  long long facePairs = 0;  ///< distinct (kept face, hidden face) pairs
  /// The first few pairs (kept face, hidden face), in order of discovery; faces are 0-based
  /// in file order. The kept face owns the lower-index triangle.
  std::vector<std::pair<int, int>> examples;
  bool empty() const { return texels == 0; }
  /// One line for a warning, e.g. "UV islands overlap on 120 texels (3 face pairs: 4/17, ...)";
  /// empty when there is no overlap.
  std::string describe() const;
};

/// The rasterised UV layout and the mesh tables a backend needs: built once per mesh and map
/// size ("far"), then evaluated for many frames. Active texels are the covered ones plus the
/// padding; each holds the triangle and barycentric weights its value is interpolated with (a
/// padded texel holds those of the covered texel it copies, so per-frame padding needs no
/// pass of its own).
///
///   triangles            T x 3   vertex ids, fan triangles of the faces (Mesh::triangulate)
///   vertexTriangleStart  V + 1   incident triangles of vertex v:
///   vertexTriangles              vertexTriangles[vertexTriangleStart[v] .. [v+1]-1], ascending
///   texels               E       texel index y * W + x of each active texel, ascending
///   texelTriangles       E       triangle under the texel centre (or under its source's)
///   texelWeights         E x 2   barycentric weights (b1, b2) of corners 1 and 2; corner 0
///                                has 1 - b1 - b2
///   texelSources         E       active index of the covered texel this one copies
///                                (itself when covered; -1 in a band of rows whose source
///                                lies in another band: PositionMapRaster::band)
///   coverage             W x H   the A channel: 1 on covered texels, 0 elsewhere
struct PositionMapTables {
  int width = 0;
  int height = 0;
  int padding = 0;
  int vertexCount = 0;
  long long coveredCount = 0;  ///< covered texels (A = 1)
  long long paddedCount = 0;   ///< padded texels (A = 0, P copied)
  std::uint64_t topologyHash = 0;
  std::vector<int> triangles;
  std::vector<int> triangleFaces;  ///< T: face of each triangle (for messages)
  std::vector<int> vertexTriangleStart;
  std::vector<int> vertexTriangles;
  std::vector<int> texels;
  std::vector<int> texelTriangles;
  std::vector<float> texelWeights;
  std::vector<int> texelSources;
  std::vector<float> coverage;
  UvOverlapReport overlaps;

  int triangleCount() const { return static_cast<int>(triangles.size() / 3); }
  std::size_t activeCount() const { return texels.size(); }
  std::size_t texelCount() const {
    return static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  }
};

// ---------------------------------------------------------------------------------------
// Position-map EXR: scanline, one file per frame, W x H, row 0 = top (see above). Channels,
// named as compositing tools name a colour image and its layers (PositionMapChannels::kRgba,
// the default; docs/formats.md says why):
//   R G B         FLOAT  world position x, y, z (the default layer: what a viewer shows)
//   A             FLOAT  1 on covered texels, 0 elsewhere (padding included)
//   N.R N.G N.B   FLOAT, or HALF with halfNormals; only when normals are written
// or, with PositionMapChannels::kLegacy (the names earlier builds wrote, for pipelines that
// read them):
//   P.X P.Y P.Z, A, N.X N.Y N.Z   the same data and types under the point cache's names
// Texels outside every UV triangle have A = 0; there the padded ones (within `padding` texels
// of an island) hold P and N of their nearest covered texel and the rest hold 0.
// Header attributes (names <= 31 bytes):
//   dsKind "positionMap" (string), dsFrame (int), dsTopologyHash (string, 16 hex digits),
//   dsToolVersion (string), dsMeshVertexCount (int), dsBoundsMin / dsBoundsMax (v3f, the
//   frame's vertex bounds), dsPadding (int), dsUvLayout (string, the convention above),
//   framesPerSecond (rational, standard).
// dsMeshVertexCount is deliberately not the point cache's dsVertexCount, so a position map is
// never mistaken for a point cache.

/// How the channels of a position-map EXR are named (see above).
enum class PositionMapChannels {
  kRgba,    ///< R G B position, A coverage, N.R N.G N.B normals: a colour image with a layer
  kLegacy,  ///< P.X P.Y P.Z, A, N.X N.Y N.Z: the names maps had before (byte-identical files)
};

/// "rgba" or "legacy" (the `--channels` values).
const char* positionMapChannelsName(PositionMapChannels channels);
/// Parses "rgba" or "legacy" (any case). Throws Error(kUsage) naming `flag`, the text and the
/// accepted values otherwise.
PositionMapChannels parsePositionMapChannels(const std::string& text,
                                             const std::string& flag = "--channels");
/// The channel names of a map in the order OpenImageIO and Nuke list them: position x, y, z,
/// coverage, then (when `normals`) the normals x, y, z. The file itself stores channels in
/// alphabetical order, as every EXR does.
std::vector<std::string> positionMapChannelNames(PositionMapChannels channels, bool normals);

struct PositionMapOptions {
  int width = 2048;
  int height = 2048;
  int padding = 8;           ///< texels of dilation, 0..kMaxPositionMapPadding
  bool normals = false;      ///< also write the normals (N.R N.G N.B)
  bool halfNormals = false;  ///< N as HALF (implies normals)
  bool preview = false;      ///< also write an 8-bit PNG per map (previewPath)
  ExrCompression compression = ExrCompression::kZip;
  ZipEncoder zipEncoder = ZipEncoder::kLibdeflate;
  double framesPerSecond = 24.0;
  int threads = 0;  ///< files written at once (0 = all cores)
  /// Frames per launch (0 = as many as fit in launchBytes of maps, at most 16; 16 for a map
  /// written in bands).
  int chunkSize = 0;
  /// Memory for the maps of one launch (P, plus N), in bytes. A map whose tables would pass four
  /// times this (counted at 64 bytes per texel with the backend's copy and the rasterisation's
  /// scratch: maps past 4096 x 4096 by default) is rasterised, evaluated and written a band of
  /// rows at a time, its tables built again for each launch, so that the maps and the band's
  /// tables stay within this bound at any size (16384 x 16384 included).
  std::size_t launchBytes = std::size_t{256} << 20;
  /// Channel names: R G B, A, N.R N.G N.B by default; kLegacy for P.X P.Y P.Z, A, N.X N.Y N.Z.
  PositionMapChannels channels = PositionMapChannels::kRgba;
};

/// Header fields of one position-map EXR.
struct PositionMapFrameHeader {
  int frame = 0;
  std::uint64_t topologyHash = 0;
  int meshVertexCount = 0;
  int padding = 0;
  Bounds bounds;
  ExrCompression compression = ExrCompression::kZip;
  ZipEncoder zipEncoder = ZipEncoder::kLibdeflate;
  int encodeThreads = 1;  ///< as ExrWriteOptions::encodeThreads
  double framesPerSecond = 24.0;
  bool halfNormals = false;
  PositionMapChannels channels = PositionMapChannels::kRgba;
};

/// Writes one position-map EXR atomically (temp file + rename). `positions` and `normals`
/// are W*H interleaved xyz (row 0 = top), `coverage` W*H; `normals` may be null.
void writePositionMapExr(const std::string& path, int width, int height, const float* positions,
                         const float* coverage, const float* normals,
                         const PositionMapFrameHeader& header);

/// Writes one position-map EXR a band of rows at a time, top to bottom: the bytes
/// writePositionMapExr writes for the whole map, through the same atomic temporary file, so that
/// a large map need never be whole in memory (PositionMapWriter writes its banded maps so). Without
/// commit() (an exception, a failed band) the temporary file is removed.
///
///     PositionMapExrWriter file(path, width, height, false, header);
///     file.writeRows(256, positions, coverage, nullptr);  // rows 0-255
///     ...                                                 // the rest, in order
///     file.commit();
class PositionMapExrWriter {
 public:
  /// Creates the temporary file; Error(kUsage) for a size or rate writePositionMapExr refuses,
  /// Error(kOutput) when the file cannot be created.
  PositionMapExrWriter(const std::string& path, int width, int height, bool normals,
                       const PositionMapFrameHeader& header);
  ~PositionMapExrWriter();
  PositionMapExrWriter(const PositionMapExrWriter&) = delete;
  PositionMapExrWriter& operator=(const PositionMapExrWriter&) = delete;
  /// The next `rows` rows: `positions` (and `normals`, when the file has them) 3 * width * rows
  /// interleaved floats, `coverage` width * rows. A ZIP file's bands but the last hold whole
  /// chunks (multiples of 16 rows). Error(kOutput) when the write fails.
  void writeRows(int rows, const float* positions, const float* coverage, const float* normals);
  /// After the last row: completes the file and renames it into place (Error(kOutput)).
  void commit();

 private:
  struct State;
  std::unique_ptr<State> mState;
};

/// What a position-map EXR's header says (`drivenshape info`).
struct PositionMapInfo : ExrSharedHeader {
  int width = 0;
  int height = 0;
  int meshVertexCount = 0;
  int padding = 0;
  bool halfNormals = false;  ///< normals stored as 16-bit floats
  /// Which names the file uses (R G B: kRgba, P.X P.Y P.Z: kLegacy).
  PositionMapChannels channels = PositionMapChannels::kRgba;
};

/// Whether `path` is an EXR whose header marks it as a position map (dsKind = positionMap);
/// false for anything else, unreadable files included.
bool isPositionMapExr(const std::string& path);

/// Reads the header of a position-map EXR and tells its channel naming from the channels
/// present (R G B: kRgba; else P.X P.Y P.Z: kLegacy). Throws Error(kInput) naming the file
/// when it does not exist, cannot be read, is not a position map or has neither set of
/// position channels.
PositionMapInfo readPositionMapExrInfo(const std::string& path);

/// Writes an 8-bit RGB PNG of one map atomically: covered texels show P scaled from `bounds`
/// to 0..255 per axis (x red, y green, z blue), padded texels the same at half brightness,
/// the rest black. For eyeballing a map, not for data.
void writePositionMapPreview(const std::string& path, const PositionMapTables& tables,
                             const float* positions, const Bounds& bounds);

/// The preview of writePositionMapPreview drawn a band of rows at a time (a map written band by
/// band): the 8-bit image (3 bytes per texel) is held until write().
class PositionMapPreview {
 public:
  PositionMapPreview(int width, int height, const Bounds& bounds);
  /// Draws the band.height rows from `firstRow` from the band's tables (PositionMapRaster::band)
  /// and `positions` (3 * band.width * band.height floats).
  void draw(const PositionMapTables& band, int firstRow, const float* positions);
  /// Writes the PNG atomically.
  void write(const std::string& path) const;

 private:
  int mWidth = 0;
  int mHeight = 0;
  Bounds mBounds;
  std::vector<unsigned char> mRows;  ///< PNG rows: a filter byte, then RGB per texel
};

/// "out/cloth.1001.exr" -> "out/cloth.1001.png" (the extension replaced or appended).
std::string positionMapPreviewPath(const std::string& exrPath);

}  // namespace drivenshape
