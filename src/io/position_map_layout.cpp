// SPDX-License-Identifier: Apache-2.0
// The position map's sizes and its report of overlapping UV islands (drivenshape/position_map.h).
#include <drivenshape/position_map.h>

#include <algorithm>
#include <cctype>
#include <cstddef>
#include <sstream>
#include <string>
#include <utility>

#include <drivenshape/error.h>

namespace drivenshape {

std::string UvOverlapReport::describe() const {
  if (texels == 0) {
    return "";
  }
  std::ostringstream text;
  text << "UV islands overlap on " << texels << " texel" << (texels == 1 ? "" : "s") << " ("
       << facePairs << " face pair" << (facePairs == 1 ? "" : "s")
       << " kept/hidden, faces counted from 1 in f-line order: ";
  for (std::size_t i = 0; i < examples.size(); ++i) {
    text << (i == 0 ? "" : ", ") << examples[i].first + 1 << "/" << examples[i].second + 1;
  }
  if (static_cast<long long>(examples.size()) < facePairs) {
    text << ", ...";
  }
  text << "); the face listed first (lower triangle index) keeps each shared texel";
  return text.str();
}

std::pair<int, int> parsePositionMapResolution(const std::string& text, const std::string& flag) {
  const auto parseSide = [&](const std::string& part) {
    if (part.empty() || part.size() > 9 ||
        !std::all_of(part.begin(), part.end(),
                     [](unsigned char ch) { return std::isdigit(ch) != 0; })) {
      DS_THROW(kUsage, flag, " '", text,
               "' is not a resolution; use W or WxH in texels, e.g. 2048 or 2048x1024");
    }
    return std::stoi(part);
  };
  const auto cross = text.find_first_of("xX");
  const int width = parseSide(text.substr(0, cross));
  const int height = cross == std::string::npos ? width : parseSide(text.substr(cross + 1));
  if (width < 1 || height < 1 || width > kMaxPositionMapSide || height > kMaxPositionMapSide) {
    DS_THROW(kUsage, flag, " '", text, "': each side must be 1..", kMaxPositionMapSide, " texels");
  }
  return {width, height};
}

}  // namespace drivenshape
