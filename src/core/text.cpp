// SPDX-License-Identifier: Apache-2.0
#include "text.h"

#include <cstdio>

namespace drivenshape {
namespace {

/// The length of the valid UTF-8 sequence at `text[i]` (1-4), or 0 when it is not one.
std::size_t utf8Length(const std::string& text, std::size_t i) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
  const unsigned char lead = byte(i);
  std::size_t length = 0;
  unsigned minimum = 0;
  unsigned code = 0;
  if (lead >= 0xc2 && lead <= 0xdf) {
    length = 2, minimum = 0x80, code = lead & 0x1fu;
  } else if (lead >= 0xe0 && lead <= 0xef) {
    length = 3, minimum = 0x800, code = lead & 0x0fu;
  } else if (lead >= 0xf0 && lead <= 0xf4) {
    length = 4, minimum = 0x10000, code = lead & 0x07u;
  } else {
    return 0;
  }
  if (i + length > text.size()) {
    return 0;
  }
  for (std::size_t k = 1; k < length; ++k) {
    if ((byte(i + k) & 0xc0u) != 0x80u) {
      return 0;
    }
    code = (code << 6) | (byte(i + k) & 0x3fu);
  }
  const bool surrogate = code >= 0xd800 && code <= 0xdfff;
  return code >= minimum && code <= 0x10ffff && !surrogate ? length : 0;
}

void appendEscaped(std::string& out, const std::string& text, std::size_t begin, std::size_t end) {
  for (std::size_t i = begin; i < end;) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c == '\n' || c == '\t' || (c >= 0x20 && c < 0x7f)) {
      out += static_cast<char>(c);
      ++i;
      continue;
    }
    const std::size_t length = c >= 0x80 ? utf8Length(text, i) : 0;
    if (length > 0 && i + length <= end) {
      out.append(text, i, length);
      i += length;
      continue;
    }
    char escaped[5];
    std::snprintf(escaped, sizeof(escaped), "\\x%02x", c);
    out += escaped;
    ++i;
  }
}

}  // namespace

bool isUtf8(const std::string& text) {
  for (std::size_t i = 0; i < text.size();) {
    const std::size_t length = static_cast<unsigned char>(text[i]) < 0x80 ? 1 : utf8Length(text, i);
    if (length == 0) {
      return false;
    }
    i += length;
  }
  return true;
}

std::string printableText(const std::string& text, std::size_t maxBytes) {
  std::string out;
  if (text.size() <= maxBytes) {
    appendEscaped(out, text, 0, text.size());
    return out;
  }
  const std::size_t keep = maxBytes / 2;
  appendEscaped(out, text, 0, keep);
  out += "...(" + std::to_string(text.size()) + " bytes)...";
  appendEscaped(out, text, text.size() - keep, text.size());
  return out;
}

}  // namespace drivenshape
