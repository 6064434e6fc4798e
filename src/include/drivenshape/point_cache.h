// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <drivenshape/mesh.h>

namespace drivenshape {

/// A per-frame sequence of vertex positions, read frame by frame.
/// Implementations: PC2 files and point-cache EXR sequences (see openPointCache).
class PointCacheReader {
 public:
  virtual ~PointCacheReader() = default;
  virtual int vertexCount() const = 0;
  /// All frames the cache holds, ascending.
  virtual std::vector<int> frames() const = 0;
  virtual bool hasFrame(int frame) const = 0;
  /// Reads one frame into `xyz` (vertexCount() * 3 floats, interleaved). Throws Error(kInput)
  /// naming the file and frame if the frame is missing or unreadable, if it holds a NaN or
  /// infinite position (naming the vertex; unless allowNonFinite), and, for an EXR sequence, if
  /// the file's header holds another frame than its name says.
  virtual void readFrame(int frame, float* xyz) const = 0;
  /// The file or pattern this reads, for messages.
  virtual const std::string& path() const = 0;
  /// Lets readFrame return NaN and infinite positions: only for a cache where they mean "not
  /// covered here" (a mix layer's other cache, where the weight map keeps the cloth).
  void allowNonFinite() { mAllowNonFinite = true; }

 protected:
  /// Throws Error(kInput) naming `source`, the frame and the vertex of the first NaN or
  /// infinite position of `xyz` (vertexCount() * 3 floats), unless allowNonFinite.
  void checkFinite(const std::string& source, int frame, const float* xyz) const;

 private:
  bool mAllowNonFinite = false;
};

/// Opens `spec`: a `.pc2` file, or an EXR sequence pattern (`out.####.exr`, `%04d`, `$F4`).
/// For EXR sequences, `expectedTopology` (if nonzero) is checked against each file's header.
/// Throws Error(kInput) if the file is missing or its header is invalid.
std::unique_ptr<PointCacheReader> openPointCache(const std::string& spec,
                                                 std::uint64_t expectedTopology = 0);

/// Reads frames [frames] of a cache into one F by (3V) row-major block (frame-major).
std::vector<float> readFrames(const PointCacheReader& cache, const std::vector<int>& frames);

/// The largest coordinate (absolute, scene units) a cache may hold where it is evaluated (the
/// bake's driver, db build's clips): far beyond any scene (10 km in centimetres), and far below
/// where float32 squared distances overflow and the closest-triangle search fails.
inline constexpr float kMaxCoordinate = 1e6f;

/// Reads one frame (as PointCacheReader::readFrame) and refuses a NaN or infinite position, or
/// one beyond +/-kMaxCoordinate, with Error(kInput) naming the file, the frame and the vertex
/// (and `role`, "driver cache", "truth", for a reader opened with allowNonFinite, whose
/// readFrame lets NaN through).
void readFiniteFrame(const PointCacheReader& cache, int frame, float* xyz, const std::string& role);

// ---------------------------------------------------------------------------------------
// PC2 (little-endian): 12-byte "POINTCACHE2\0", int32 version (1), int32 points,
// float32 start frame, float32 sample rate, int32 samples, then samples * points * xyz float32.
// Sample s holds frame start + s * rate. Frames that fall between samples are not readable.

struct Pc2Header {
  int points = 0;
  float startFrame = 1.0f;
  float sampleRate = 1.0f;
  int samples = 0;
};

/// Opens a PC2 file (header validated, size checked against the header: a truncated file
/// is refused with the byte counts in the message).
std::unique_ptr<PointCacheReader> openPc2(const std::string& path);

/// Writes frames (F by 3V floats, frame-major) as PC2 starting at `startFrame`, one sample every
/// `sampleRate` frames (1 = consecutive frames; 2 for 1001-1100x2), atomically. The header is
/// what Blender's Mesh Cache modifier and Maya's PC2 conversion read: "POINTCACHE2\0", version 1,
/// points, start frame, sample rate, sample count. Throws Error(kUsage) for a rate that is not
/// positive.
void writePc2(const std::string& path, int vertexCount, float startFrame, int frameCount,
              const float* xyz, float sampleRate = 1.0f);

/// Streams a PC2 file frame by frame (for caches too big to hold at once), atomically: the file
/// appears under `path` only at commit(), after exactly `frameCount` frames were written.
class Pc2Writer {
 public:
  /// Throws Error(kOutput) when the file cannot be created, Error(kUsage) for a bad rate.
  Pc2Writer(const std::string& path, int vertexCount, float startFrame, int frameCount,
            float sampleRate = 1.0f);
  ~Pc2Writer();
  Pc2Writer(const Pc2Writer&) = delete;
  Pc2Writer& operator=(const Pc2Writer&) = delete;
  /// Appends one frame of vertexCount * 3 floats.
  void writeFrame(const float* xyz);
  /// Flushes and renames into place; throws unless every promised frame was written.
  void commit();

 private:
  struct State;
  std::unique_ptr<State> mState;
};

// ---------------------------------------------------------------------------------------
// Point-cache EXR: one file per frame. Vertex v is pixel (v mod W, v div W); H = ceil(V/W).
//
//   row 0:  v0      v1      ...  v(W-1)
//   row 1:  vW      vW+1    ...
//   ...     last row padded with A = 0, P = 0
//
// Channels P.X P.Y P.Z A (FLOAT), optional N.X N.Y N.Z. Header attributes (<= 31 bytes):
//   dsVertexCount (int), dsFrame (int), dsTopologyHash (string, 16 hex digits),
//   dsToolVersion (string), dsBoundsMin / dsBoundsMax (v3f), dsSettingsHash (string, optional),
//   framesPerSecond (rational, standard).

enum class ExrCompression { kZip, kNone, kZips, kPiz };
/// Parses `zip|none|zips|piz`; throws Error(kUsage) naming the value otherwise.
ExrCompression parseExrCompression(const std::string& text);
const char* exrCompressionName(ExrCompression compression);

/// Which encoder deflates ZIP and ZIPS files. Both write standard files that every OpenEXR
/// reader (OpenEXR's own and oiiotool are tested) decodes to the same pixels; only the
/// compressed bytes differ, by less than 0.2% in size (docs/exr_options.md).
enum class ZipEncoder {
  /// libdeflate (level 1), the chunks of a file on ExrWriteOptions::encodeThreads threads:
  /// 2.2-3.8 times less CPU than kOpenExr.
  kLibdeflate,
  /// OpenEXR's own writer (zlib at OpenEXR 3.1's level 4): byte for byte the files of builds
  /// before the libdeflate encoder (`--zip-encoder openexr`).
  kOpenExr,
};
/// Parses `libdeflate|openexr` (any case); throws Error(kUsage) naming `flag` and the value
/// otherwise.
ZipEncoder parseZipEncoder(const std::string& text, const std::string& flag = "--zip-encoder");
const char* zipEncoderName(ZipEncoder encoder);

/// Widest point-cache EXR accepted, in pixels (vertices per row): writePointCacheExr refuses
/// wider ones with Error(kUsage) before allocating (a row is padded out to the full width).
inline constexpr int kMaxPointCacheExrWidth = 65536;

struct ExrWriteOptions {
  int width = 1024;  ///< 1..kMaxPointCacheExrWidth
  ExrCompression compression = ExrCompression::kZip;
  ZipEncoder zipEncoder = ZipEncoder::kLibdeflate;
  /// Threads that deflate the chunks of one file with kLibdeflate (ZIP: 16 rows of pixels per
  /// chunk, so a file of 16 rows or fewer is one chunk; ZIPS: one row); below 1 counts as 1.
  int encodeThreads = 1;
  int frame = 0;
  std::uint64_t topologyHash = 0;
  std::uint64_t settingsHash = 0;  ///< 0: attribute not written
  double framesPerSecond = 24.0;
  /// Extra string attributes (name, value), e.g. {"dsLayers", LayerStack::describe()}. Names
  /// are at most 31 bytes and must not be one of the attributes above (Error(kUsage)).
  std::vector<std::pair<std::string, std::string>> stringAttributes;
  /// fsync before the atomic rename (see AtomicFile::commit): survives a power loss, costs a
  /// disk round trip per file.
  bool syncToDisk = true;
};

/// Writes one point-cache EXR frame atomically (temp file + rename). `normals` may be null.
void writePointCacheExr(const std::string& path, int vertexCount, const float* xyz,
                        const float* normals, const ExrWriteOptions& options);

/// The header fields that point-cache and position-map EXRs share (same attribute names, same
/// meaning). A missing attribute keeps its default.
struct ExrSharedHeader {
  int frame = 0;
  bool hasFrame = false;  ///< the file has the frame attribute (`frame` is 0 otherwise)
  std::uint64_t topologyHash = 0;
  std::string toolVersion;
  double framesPerSecond = 0.0;  ///< 0 when the file has none
  Bounds bounds;
  bool hasNormals = false;  ///< N.X, N.Y and N.Z all present (a position map's: its naming's)
  ExrCompression compression = ExrCompression::kZip;
};

struct ExrPointCacheInfo : ExrSharedHeader {
  int vertexCount = 0;
  int width = 0;
  std::uint64_t settingsHash = 0;
  /// CRC-32 (zlib's) of all pixel data as written: every channel in the file's (alphabetical)
  /// order as a W x H plane of float32, little-endian. writePointCacheExr stores it
  /// (dsPixelsCrc32) so that damage which still decodes can be found (reuseProblem).
  std::uint32_t pixelsCrc = 0;
  bool hasPixelsCrc = false;
  /// String attributes other than the ones above (ExrWriteOptions::stringAttributes), by name.
  std::map<std::string, std::string> stringAttributes;
};

/// Reads only the header. Throws Error(kInput) if the file is not a point-cache EXR.
ExrPointCacheInfo readPointCacheExrInfo(const std::string& path);

/// Reads positions into `xyz` (vertexCount * 3). If `expectedVertexCount` or
/// `expectedTopology` is nonzero and differs from the header, throws Error(kInput) naming the
/// file, both values and what to do. Missing P channels are an error too.
ExrPointCacheInfo readPointCacheExr(const std::string& path, std::vector<float>& xyz,
                                    int expectedVertexCount = 0,
                                    std::uint64_t expectedTopology = 0);

/// The headers of a point-cache EXR sequence (checkPointCacheExrSequence).
struct ExrSequenceInfo {
  std::vector<int> frames;         ///< ascending
  std::vector<std::string> files;  ///< files[i] holds frames[i]
  ExrPointCacheInfo first;         ///< the header of the first frame's file
};

/// Reads the header of every file of the point-cache EXR sequence `pattern` (headers only: no
/// pixel is decoded) and checks them against their names and each other: each file's frame
/// attribute (dsFrame, where present) is the frame its name says, every file is complete
/// (isCompleteExr: its offset table and first and last chunks, not its pixels), and every file
/// has the first one's vertex count and topology hash. Throws Error(kInput) naming the file and
/// the frame of the first mismatch, or as openPointCache does for a pattern that matches no
/// file.
ExrSequenceInfo checkPointCacheExrSequence(const std::string& pattern);

/// True if the file exists and OpenEXR reports it complete (all scanlines present).
bool isCompleteExr(const std::string& path);

/// Why the existing point-cache EXR at `path` cannot be kept as frame `frame` of a bake that
/// writes `vertexCount` vertices with these topology and settings hashes, or "" when it can
/// (a resumed bake, `--skip-existing`). The file must decode completely (every pixel, not only
/// the header), match the vertex count, both hashes and the frame number, and its positions
/// must match the CRC written with them, which finds a changed byte that still decodes.
/// When it can and `header` is not null, *header receives the file's header (its string
/// attributes: the frame record a bake stores), read by the same open.
std::string reuseProblem(const std::string& path, int vertexCount, std::uint64_t topology,
                         std::uint64_t settings, int frame, ExrPointCacheInfo* header = nullptr);

}  // namespace drivenshape
