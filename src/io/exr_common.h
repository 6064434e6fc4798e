// SPDX-License-Identifier: Apache-2.0
// OpenEXR helpers shared by point-cache EXRs (io/exr_point_cache.cpp) and position-map EXRs
// (io/posmap_exr.cpp). Private to the library; not installed.

#pragma once

#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <cstddef>
#include <functional>
#include <memory>
#include <ostream>
#include <string>

#include <drivenshape/point_cache.h>

namespace drivenshape::exr_detail {

// Header attribute and channel names common to both kinds of file (all well under OpenEXR's
// 31-byte limit); they mean the same thing in each.
inline constexpr const char* kAttrFrame = "dsFrame";
inline constexpr const char* kAttrTopologyHash = "dsTopologyHash";
inline constexpr const char* kAttrToolVersion = "dsToolVersion";
inline constexpr const char* kAttrBoundsMin = "dsBoundsMin";
inline constexpr const char* kAttrBoundsMax = "dsBoundsMax";
inline constexpr const char* kPositionChannels[3] = {"P.X", "P.Y", "P.Z"};
inline constexpr const char* kNormalChannels[3] = {"N.X", "N.Y", "N.Z"};
inline constexpr const char* kCoverageChannel = "A";

Imf::Compression toImf(ExrCompression compression);

/// The four lossless codecs we write map back exactly; a file re-saved elsewhere with another
/// codec reports the nearest lossless one (RLE -> none, anything else -> zip).
ExrCompression fromImf(Imf::Compression compression);

/// Opens `path` for reading, after checking what OpenEXR would otherwise trust from the file:
/// every header attribute fits in the file, the image is single-part scan lines, and its data
/// window and channels describe no more pixel data than a file of this size can decode to
/// (OpenEXR sizes its tables and our readers size their buffers from those fields). A file that
/// fails is Error(kInput) "<kind> EXR '<path>': ..."; so is anything OpenEXR throws on open.
std::unique_ptr<Imf::InputFile> openExr(const std::string& path, const char* kind);

/// The shared header fields (ExrSharedHeader); a malformed topology hash is Error(kInput)
/// naming `path`.
ExrSharedHeader readSharedHeader(const std::string& path, const Imf::Header& header);

/// FLOAT slices of an interleaved xyz image (3 floats per pixel, `width` pixels per row) for the
/// three channels `names`. OpenEXR only reads through the slices when writing.
void insertXyzSlices(Imf::FrameBuffer& frameBuffer, const char* const names[3], const float* base,
                     std::size_t width);

/// Writes `path` atomically: `body` writes the file through the stream it is given (the
/// exclusively created temporary file of `path`, see AtomicFile; with writeScanlines) and the
/// file is renamed into place once `body` returns. drivenshape::Error
/// passes through; any other exception becomes Error(kOutput) "cannot write <kind> EXR '<path>'".
/// `syncToDisk`: fsync before the rename (AtomicFile::commit).
void writeExrAtomically(const std::string& path, const char* kind,
                        const std::function<void(std::ostream& stream)>& body,
                        bool syncToDisk = true);

/// Writes the scan lines of one image to `stream` (the temporary file of `path`) a band at a
/// time, top to bottom, the bytes writeScanlines writes at once: a large image need never be
/// whole in memory. ZIP and ZIPS images with ZipEncoder::kLibdeflate go through ZipExrWriter
/// (io/exr_zip_writer.h; each band but the last whole chunks of 16 lines), everything else
/// through OpenEXR's writer on our own stream. A failed write is Error(kOutput) naming `path`.
class ScanlineWriter {
 public:
  ScanlineWriter(const std::string& path, std::ostream& stream, const Imf::Header& header,
                 ZipEncoder zipEncoder, int encodeThreads);
  ~ScanlineWriter();
  ScanlineWriter(const ScanlineWriter&) = delete;
  ScanlineWriter& operator=(const ScanlineWriter&) = delete;
  /// The next `lines` scan lines, read through `frameBuffer`, whose slices are addressed by
  /// absolute y (as OpenEXR's).
  void write(const Imf::FrameBuffer& frameBuffer, int lines);
  /// After the last line: the offset table, the stream flushed and checked.
  void finish();

 private:
  void checkStream() const;

  struct State;
  std::string mPath;
  std::ostream& mStream;
  std::unique_ptr<State> mState;
};

/// Writes the `height` scan lines of `frameBuffer` with `header` to `stream` (the temporary
/// file of `path`) in one band of ScanlineWriter: ZIP and ZIPS images with
/// ZipEncoder::kLibdeflate through ZipExrWriter (io/exr_zip_writer.h) on `encodeThreads` threads;
/// everything else through OpenEXR's writer on our own stream, so that a failure while its
/// destructor writes the offset table (which it swallows) still shows up as Error(kOutput).
void writeScanlines(const std::string& path, std::ostream& stream, const Imf::Header& header,
                    const Imf::FrameBuffer& frameBuffer, int height, ZipEncoder zipEncoder,
                    int encodeThreads);

}  // namespace drivenshape::exr_detail
