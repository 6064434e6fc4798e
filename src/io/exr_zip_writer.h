// SPDX-License-Identifier: Apache-2.0
// Standard ZIP and ZIPS scan-line EXR files whose chunks are deflated by libdeflate (or zlib)
// on several threads: the file layout of Imf::OutputFile, header bytes included, with only the
// deflate streams different. Private to the libraries in src/; not installed. Measurements and
// the reasons for it: docs/exr_options.md.

#pragma once

#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>

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

/// Writes to `out` the whole file that Imf::OutputFile would write for `header` and
/// `frameBuffer`, with each chunk deflated as `encoding` says. The header's compression must be
/// ZIP or ZIPS, its line order INCREASING_Y, and every channel's slice of the same pixel type as
/// the channel (or absent: zeros, as OpenEXR writes); other input is Error(kInternal). The host
/// must be little-endian (EXR's byte order). Holds the compressed chunks in memory until they
/// are written; the caller checks `out` for write errors.
void writeZipExr(std::ostream& out, const Imf::Header& header, const Imf::FrameBuffer& frameBuffer,
                 const ZipEncoding& encoding);

/// writeZipExr into memory: the file's bytes.
std::string encodeZipExr(const Imf::Header& header, const Imf::FrameBuffer& frameBuffer,
                         const ZipEncoding& encoding);

}  // namespace drivenshape::exr_detail
