// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/mesh.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string_view>
#include <unordered_map>

#include <drivenshape/error.h>
#include <drivenshape/version.h>
#include "atomic_file.h"

namespace drivenshape {
namespace {

bool isSpace(char ch) {
  return ch == ' ' || ch == '\t' || ch == '\r' || ch == '\f' || ch == '\v';
}

/// `text` if it is valid UTF-8, else the same bytes read as Latin-1 (each byte its own code
/// point), so that names from older exporters stay distinct and every name is valid UTF-8 in
/// JSON headers and reports.
std::string utf8OrLatin1(const std::string& text) {
  bool valid = true;
  for (std::size_t i = 0; i < text.size() && valid;) {
    const auto lead = static_cast<unsigned char>(text[i]);
    std::size_t length = 0;  // 0: not a lead byte
    if (lead < 0x80) {
      length = 1;
    } else if ((lead >> 5) == 0x6) {
      length = 2;
    } else if ((lead >> 4) == 0xe) {
      length = 3;
    } else if ((lead >> 3) == 0x1e) {
      length = 4;
    }
    valid = length > 0 && i + length <= text.size();
    std::uint32_t code = length == 1 ? lead : lead & (0x7fu >> length);
    for (std::size_t k = 1; valid && k < length; ++k) {
      const auto next = static_cast<unsigned char>(text[i + k]);
      valid = (next & 0xc0) == 0x80;
      code = (code << 6) | (next & 0x3fu);
    }
    // No overlong forms, no surrogates, nothing past U+10FFFF.
    static constexpr std::uint32_t kSmallest[5] = {0, 0, 0x80, 0x800, 0x10000};
    valid =
        valid && code >= kSmallest[length] && code <= 0x10ffff && (code < 0xd800 || code > 0xdfff);
    i += length;
  }
  if (valid) {
    return text;
  }
  std::string converted;
  for (const char ch : text) {
    const auto byte = static_cast<unsigned char>(ch);
    if (byte < 0x80) {
      converted.push_back(ch);
    } else {
      converted.push_back(static_cast<char>(0xc0 | (byte >> 6)));
      converted.push_back(static_cast<char>(0x80 | (byte & 0x3f)));
    }
  }
  return converted;
}

/// Walks the whitespace-separated tokens of one line.
class Tokens {
 public:
  Tokens(const char* begin, const char* end) : mPos(begin), mEnd(end) {}
  bool next(std::string_view& token) {
    while (mPos < mEnd && isSpace(*mPos)) {
      ++mPos;
    }
    if (mPos == mEnd) {
      return false;
    }
    const char* start = mPos;
    while (mPos < mEnd && !isSpace(*mPos)) {
      ++mPos;
    }
    token = std::string_view(start, static_cast<std::size_t>(mPos - start));
    return true;
  }
  /// The rest of the line without surrounding whitespace (group names may hold spaces).
  std::string rest() {
    while (mPos < mEnd && isSpace(*mPos)) {
      ++mPos;
    }
    const char* end = mEnd;
    while (end > mPos && isSpace(end[-1])) {
      --end;
    }
    return std::string(mPos, end);
  }

 private:
  const char* mPos;
  const char* mEnd;
};

class ObjParser {
 public:
  explicit ObjParser(const std::string& path) : mPath(path) {}

  Mesh parse(const std::string& bytes) {
    mMesh.faceStart.push_back(0);
    const char* pos = bytes.data();
    const char* end = pos + bytes.size();
    while (pos < end) {
      ++mLine;
      const char* lineEnd = static_cast<const char*>(std::memchr(pos, '\n', end - pos));
      if (lineEnd == nullptr) {
        lineEnd = end;
      }
      parseLine(pos, lineEnd);
      pos = lineEnd + 1;
    }
    return finish();
  }

 private:
  template <typename... Args>
  [[noreturn]] void fail(const Args&... args) const {
    DS_THROW(kInput, mPath, ":", mLine, ": ", args...);
  }

  float parseFloat(std::string_view token, const char* what) const {
    const char* begin = token.data();
    const char* end = begin + token.size();
    if (begin < end && *begin == '+') {
      ++begin;
    }
    float value = 0.0f;
    const auto result = std::from_chars(begin, end, value);
    if (result.ec != std::errc() || result.ptr != end || !std::isfinite(value)) {
      fail("malformed number '", token, "' in ", what);
    }
    return value;
  }

  void parseLine(const char* begin, const char* end) {
    Tokens tokens(begin, end);
    std::string_view keyword;
    if (!tokens.next(keyword) || keyword[0] == '#') {
      return;
    }
    if (keyword == "v") {
      std::string_view token;
      for (int k = 0; k < 3; ++k) {
        if (!tokens.next(token)) {
          fail("vertex line has ", k, " coordinates; expected x y z");
        }
        mPositions.push_back(parseFloat(token, "vertex position"));
      }
    } else if (keyword == "vt") {
      std::string_view token;
      Eigen::Vector2f uv(0.0f, 0.0f);
      if (!tokens.next(token)) {
        fail("texture coordinate line has no values; expected u [v]");
      }
      uv.x() = parseFloat(token, "texture coordinate");
      if (tokens.next(token)) {
        uv.y() = parseFloat(token, "texture coordinate");
      }
      mMesh.uvs.push_back(uv);
    } else if (keyword == "f") {
      parseFace(tokens);
    } else if (keyword == "g" || keyword == "o") {
      mGroupName = utf8OrLatin1(tokens.rest());
      if (mGroupName.empty()) {
        mGroupName = "default";
      }
      mGroupId = -1;
    }
    // vn, vp, usemtl, mtllib, s, l, p and unknown statements carry nothing we keep.
  }

  /// Parses an index field; returns false if the field is empty.
  bool parseIndex(std::string_view field, std::string_view corner, int& value) const {
    if (field.empty()) {
      return false;
    }
    const auto result = std::from_chars(field.data(), field.data() + field.size(), value);
    if (result.ec != std::errc() || result.ptr != field.data() + field.size()) {
      fail("malformed index '", field, "' in face corner '", corner, "'");
    }
    if (value == 0) {
      fail("index 0 in face corner '", corner, "'; OBJ indices start at 1 (or -1 for the last)");
    }
    return true;
  }

  /// OBJ index -> 0-based id. Negative indices count back from what is defined so far;
  /// positive ones are range checked once the whole file is read.
  int resolve(int index, int definedSoFar, const char* what, const char* plural,
              std::string_view corner) const {
    if (index > 0) {
      return index - 1;
    }
    // In 64 bits: -index overflows an int for INT_MIN.
    if (-static_cast<long long>(index) > definedSoFar) {
      fail(what, " index ", index, " in face corner '", corner, "' is out of range: only ",
           definedSoFar, " ", plural, " are defined before this line");
    }
    return definedSoFar + index;
  }

  void parseFace(Tokens& tokens) {
    if (mMesh.faceVertices.size() >= static_cast<std::size_t>(std::numeric_limits<int>::max())) {
      fail("more face corners than this reader supports (", std::numeric_limits<int>::max(), ")");
    }
    const int vertexCount = static_cast<int>(mPositions.size() / 3);
    const int uvCount = static_cast<int>(mMesh.uvs.size());
    std::string_view corner;
    int corners = 0;
    while (tokens.next(corner)) {
      const std::size_t slash1 = corner.find('/');
      const std::string_view vField = corner.substr(0, slash1);
      std::string_view tField;
      std::string_view nField;
      if (slash1 != std::string_view::npos) {
        const std::size_t slash2 = corner.find('/', slash1 + 1);
        tField = corner.substr(slash1 + 1, slash2 == std::string_view::npos ? std::string_view::npos
                                                                            : slash2 - slash1 - 1);
        if (slash2 != std::string_view::npos) {
          nField = corner.substr(slash2 + 1);
        }
      }
      int index = 0;
      if (!parseIndex(vField, corner, index)) {
        fail("face corner '", corner, "' has no vertex index");
      }
      mMesh.faceVertices.push_back(resolve(index, vertexCount, "vertex", "vertices", corner));
      if (parseIndex(tField, corner, index)) {
        mMesh.faceUvs.push_back(
            resolve(index, uvCount, "texture coordinate", "texture coordinates", corner));
        mAnyUv = true;
      } else {
        mMesh.faceUvs.push_back(-1);
      }
      int normal = 0;
      parseIndex(nField, corner, normal);  // syntax only: normals are not kept
      ++corners;
    }
    if (corners < 3) {
      fail("face has ", corners, " vertices; a face needs at least 3");
    }
    mMesh.faceStart.push_back(static_cast<int>(mMesh.faceVertices.size()));
    if (mGroupId < 0) {
      const auto found = mGroupIds.find(mGroupName);
      if (found != mGroupIds.end()) {
        mGroupId = found->second;
      } else {
        mGroupId = static_cast<int>(mMesh.groupNames.size());
        mGroupIds.emplace(mGroupName, mGroupId);
        mMesh.groupNames.push_back(mGroupName);
      }
    }
    mMesh.faceGroup.push_back(mGroupId);
    mFaceLine.push_back(mLine);
  }

  Mesh finish() {
    const int vertexCount = static_cast<int>(mPositions.size() / 3);
    if (vertexCount == 0) {
      DS_THROW(kInput, mPath, ": no vertices ('v' lines); is this an OBJ file?");
    }
    if (mPositions.size() / 3 > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
      DS_THROW(kInput, mPath, ": more vertices than this reader supports");
    }
    const int uvCount = static_cast<int>(mMesh.uvs.size());
    for (std::size_t f = 0; f < mFaceLine.size(); ++f) {
      for (int c = mMesh.faceStart[f]; c < mMesh.faceStart[f + 1]; ++c) {
        const int v = mMesh.faceVertices[c];
        if (v >= vertexCount) {
          DS_THROW(kInput, mPath, ":", mFaceLine[f], ": vertex index ", v + 1,
                   " is out of range: the file has ", vertexCount, " vertices");
        }
        const int t = mMesh.faceUvs[c];
        if (t >= uvCount) {
          DS_THROW(kInput, mPath, ":", mFaceLine[f], ": texture coordinate index ", t + 1,
                   " is out of range: the file has ", uvCount, " texture coordinates");
        }
      }
    }
    if (!mAnyUv) {
      mMesh.faceUvs.clear();
    }
    mMesh.positions = Eigen::Map<const Positions>(mPositions.data(), vertexCount, 3);
    validateMesh(mMesh, mPath);
    mMesh.triangulate();
    return std::move(mMesh);
  }

  const std::string& mPath;
  Mesh mMesh;
  std::vector<float> mPositions;
  std::vector<int> mFaceLine;
  std::unordered_map<std::string, int> mGroupIds;
  std::string mGroupName = "default";
  int mGroupId = -1;
  bool mAnyUv = false;
  int mLine = 0;
};

void appendFloat(std::string& out, float value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, result.ptr);
}

void appendInt(std::string& out, int value) {
  char buffer[16];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, result.ptr);
}

}  // namespace

Mesh readObj(const std::string& path) {
  const std::string bytes = readWholeFile(path, "OBJ");
  return ObjParser(path).parse(bytes);
}

void writeObj(const std::string& path, const Mesh& mesh) {
  std::string out;
  out.reserve(static_cast<std::size_t>(mesh.vertexCount()) * 40 + mesh.uvs.size() * 30 +
              mesh.faceVertices.size() * 14);
  out += "# drivenshape ";
  out += kVersion;
  out += '\n';
  for (int v = 0; v < mesh.vertexCount(); ++v) {
    out += 'v';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      appendFloat(out, mesh.positions(v, k));
    }
    out += '\n';
  }
  for (const Eigen::Vector2f& uv : mesh.uvs) {
    out += "vt ";
    appendFloat(out, uv.x());
    out += ' ';
    appendFloat(out, uv.y());
    out += '\n';
  }
  const int faces = mesh.faceStart.empty() ? 0 : static_cast<int>(mesh.faceStart.size()) - 1;
  const bool groups = static_cast<int>(mesh.faceGroup.size()) == faces && !mesh.groupNames.empty();
  int currentGroup = -1;
  for (int f = 0; f < faces; ++f) {
    if (groups && mesh.faceGroup[f] != currentGroup) {
      currentGroup = mesh.faceGroup[f];
      out += "g ";
      out += mesh.groupNames.at(static_cast<std::size_t>(currentGroup));
      out += '\n';
    }
    out += 'f';
    for (int c = mesh.faceStart[f]; c < mesh.faceStart[f + 1]; ++c) {
      out += ' ';
      appendInt(out, mesh.faceVertices[c] + 1);
      if (mesh.hasUvs() && mesh.faceUvs[c] >= 0) {
        out += '/';
        appendInt(out, mesh.faceUvs[c] + 1);
      }
    }
    out += '\n';
  }
  writeFileAtomically(path, out);
}

}  // namespace drivenshape
