// SPDX-License-Identifier: Apache-2.0
// Standard ZIP and ZIPS scan-line EXR files whose chunks are deflated by libdeflate (or zlib)
// on several threads: the file layout of Imf::OutputFile, header bytes included, with only the
// deflate streams different. Private to the libraries in src/; not installed. Measurements and
// the reasons for it: docs/exr_options.md.

#pragma once

#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>

#include <memory>
#include <ostream>
#include <string>

namespace drivenshape::exr_detail {

/// The deflate implementation behind encodeZipExr.
enum class Deflater { kLibdeflate, kZlib };

/// How the chunks of a ZIP or ZIPS file are deflated. The file is a standard ZIP (ZIPS) EXR
/// either way: every OpenEXR reader decodes it to the same pixels.
struct ZipEncoding {
  Deflater deflater = Deflater::kLibdeflate;
  /// 1..12 for libdeflate, 1..9 for zlib.
  int level = 1;
  /// Threads deflating the chunks (16 scan lines each for ZIP, 1 for ZIPS) of one file.
  int threads = 1;
};

/// Writes a ZIP or ZIPS file as writeZipExr does, a band of scan lines at a time, so that a large
/// image need never be whole in memory:
///
///     ZipExrWriter writer(out, header, encoding);   // the head, room for the offset table
///     writer.writeLines(band1, 1344);               // whole chunks, top to bottom
///     writer.writeLines(band2, 1344); ...
///     writer.finish();                              // the offset table (`out` seeks back)
///
/// The slices of each band's frame buffer are addressed by absolute y, as OpenEXR's are. `out`
/// must be seekable; the bytes are writeZipExr's. Input writeZipExr refuses, lines that are not
/// whole chunks (but the last) or a finish() before the last line are Error(kInternal).
class ZipExrWriter {
 public:
  ZipExrWriter(std::ostream& out, const Imf::Header& header, const ZipEncoding& encoding);
  ~ZipExrWriter();
  ZipExrWriter(const ZipExrWriter&) = delete;
  ZipExrWriter& operator=(const ZipExrWriter&) = delete;
  /// Deflates and writes the next `lines` scan lines; holds only their chunks meanwhile.
  void writeLines(const Imf::FrameBuffer& frameBuffer, int lines);
  void finish();

 private:
  struct State;
  std::unique_ptr<State> mState;
};

/// Writes to `out` the whole file that Imf::OutputFile would write for `header` and
/// `frameBuffer`, with each chunk deflated as `encoding` says. The header's compression must be
/// ZIP or ZIPS, its line order INCREASING_Y, and every channel's slice of the same pixel type as
/// the channel (or absent: zeros, as OpenEXR writes); other input is Error(kInternal). The host
/// must be little-endian (EXR's byte order). Holds the compressed chunks in memory until they
/// are written (one band of ZipExrWriter); the caller checks `out` for write errors.
void writeZipExr(std::ostream& out, const Imf::Header& header, const Imf::FrameBuffer& frameBuffer,
                 const ZipEncoding& encoding);

/// writeZipExr into memory: the file's bytes.
std::string encodeZipExr(const Imf::Header& header, const Imf::FrameBuffer& frameBuffer,
                         const ZipEncoding& encoding);

}  // namespace drivenshape::exr_detail
