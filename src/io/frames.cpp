// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/frames.h>

#include <sys/stat.h>

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <map>

#include <drivenshape/error.h>

#include "text.h"

#include "frame_token.h"

namespace drivenshape {
namespace {

/// A range that expands to more frames than this is a typo (1001-10000000), not a shot.
constexpr std::int64_t kMaxFrames = 10'000'000;

const char* const kRangeHelp = "write e.g. 1001, 1001-1100, 1001-1100x2 or 1001,1005,1010-1020";

/// Where an item sits in the whole text, for messages: "" when the item is the whole text.
std::string inText(const std::string& item, const std::string& text) {
  return item == trimSpaces(text) ? std::string() : " (in '" + text + "')";
}

/// Parses an int at `pos` (optional leading '-'); advances `pos`. False if there is none.
bool parseInt(const std::string& item, std::size_t& pos, int& value, bool& overflow) {
  const char* begin = item.data() + pos;
  const char* end = item.data() + item.size();
  const auto result = std::from_chars(begin, end, value);
  if (result.ec == std::errc::result_out_of_range) {
    overflow = true;
    return false;
  }
  if (result.ec != std::errc()) {
    return false;
  }
  pos = static_cast<std::size_t>(result.ptr - item.data());
  return true;
}

void appendItem(const std::string& item, const std::string& text, std::vector<int>& frames) {
  if (item.empty()) {
    DS_THROW(kUsage, "frame range '", text, "' has an empty item; ", kRangeHelp);
  }
  const auto malformed = [&]() {
    DS_THROW(kUsage, "frame range '", item, "'", inText(item, text),
             " is not a frame, a range or a stepped range; ", kRangeHelp);
  };
  std::size_t pos = 0;
  int first = 0;
  int last = 0;
  int step = 1;
  bool overflow = false;
  if (!parseInt(item, pos, first, overflow)) {
    if (overflow) {
      DS_THROW(kUsage, "frame range '", item, "'", inText(item, text),
               ": frame number out of range");
    }
    malformed();
  }
  last = first;
  if (pos < item.size()) {
    if (item[pos] != '-') {
      malformed();
    }
    ++pos;
    if (!parseInt(item, pos, last, overflow)) {
      if (overflow) {
        DS_THROW(kUsage, "frame range '", item, "'", inText(item, text),
                 ": frame number out of range");
      }
      malformed();
    }
    if (pos < item.size()) {
      if (item[pos] != 'x' && item[pos] != 'X') {
        malformed();
      }
      ++pos;
      if (!parseInt(item, pos, step, overflow) || pos != item.size()) {
        if (overflow) {
          DS_THROW(kUsage, "frame range '", item, "'", inText(item, text), ": step out of range");
        }
        malformed();
      }
      if (step <= 0) {
        DS_THROW(kUsage, "frame range '", item, "'", inText(item, text), " has step ", step,
                 "; the step must be a positive number of frames");
      }
    }
  }
  if (first > last) {
    const std::string stepText =
        item.find_first_of("xX") != std::string::npos ? "x" + std::to_string(step) : std::string();
    DS_THROW(kUsage, "frame range '", item, "'", inText(item, text), " runs backwards; write ",
             last, "-", first, stepText);
  }
  const std::int64_t count = (static_cast<std::int64_t>(last) - first) / step + 1;
  if (count + static_cast<std::int64_t>(frames.size()) > kMaxFrames) {
    DS_THROW(kUsage, "frame range '", text, "' holds more than ", kMaxFrames,
             " frames; check the numbers");
  }
  for (std::int64_t frame = first; frame <= last; frame += step) {
    frames.push_back(static_cast<int>(frame));
  }
}

/// `frames` without repeats, each where it first appears. Costs a sorted copy, not a hash set
/// per frame (a range of ten million frames is refused later, by the driver, in a second).
std::vector<int> withoutRepeats(std::vector<int> frames) {
  std::vector<int> sorted = frames;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end()) {
    return frames;
  }
  sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
  std::vector<bool> kept(sorted.size(), false);
  std::vector<int> unique;
  unique.reserve(sorted.size());
  for (int frame : frames) {
    const auto at = static_cast<std::size_t>(std::lower_bound(sorted.begin(), sorted.end(), frame) -
                                             sorted.begin());
    if (!kept[at]) {
      kept[at] = true;
      unique.push_back(frame);
    }
  }
  return unique;
}

}  // namespace

namespace io {

std::vector<FrameToken> findFrameTokens(const std::string& pattern) {
  std::vector<FrameToken> tokens;
  std::size_t i = 0;
  const std::size_t n = pattern.size();
  while (i < n) {
    const char ch = pattern[i];
    if (ch == '#') {
      std::size_t end = i;
      while (end < n && pattern[end] == '#') {
        ++end;
      }
      tokens.push_back({i, end - i, static_cast<int>(end - i)});
      i = end;
      continue;
    }
    if (ch == '%') {
      // %d, %0Nd (zero padded), %Nd (read as zero padded too: spaces make no file names)
      std::size_t end = i + 1;
      while (end < n && pattern[end] >= '0' && pattern[end] <= '9') {
        ++end;
      }
      if (end < n && pattern[end] == 'd' && end - i - 1 <= 3) {
        const int width = end > i + 1 ? std::atoi(pattern.substr(i + 1, end - i - 1).c_str()) : 0;
        tokens.push_back({i, end + 1 - i, width});
        i = end + 1;
        continue;
      }
    }
    if (ch == '$' && i + 1 < n && pattern[i + 1] == 'F') {
      std::size_t end = i + 2;
      while (end < n && end < i + 4 && pattern[end] >= '0' && pattern[end] <= '9') {
        ++end;
      }
      const int width = end > i + 2 ? std::atoi(pattern.substr(i + 2, end - i - 2).c_str()) : 0;
      tokens.push_back({i, end - i, width});
      i = end;
      continue;
    }
    ++i;
  }
  return tokens;
}

std::string formatFrameNumber(int frame, int width) {
  const std::int64_t wide = frame;
  std::string digits = std::to_string(wide < 0 ? -wide : wide);
  if (static_cast<int>(digits.size()) < width) {
    digits.insert(0, static_cast<std::size_t>(width) - digits.size(), '0');
  }
  return frame < 0 ? "-" + digits : digits;
}

std::map<int, std::string> listSequenceFiles(const std::string& pattern, std::error_code& ec) {
  std::map<int, std::string> found;
  const std::vector<FrameToken> tokens = findFrameTokens(pattern);
  const std::size_t nameStart =
      pattern.size() - std::filesystem::path(pattern).filename().string().size();
  if (tokens.size() != 1 || tokens.front().pos < nameStart) {
    return found;
  }
  const FrameToken& token = tokens.front();
  const std::string prefix = pattern.substr(nameStart, token.pos - nameStart);
  const std::string suffix = pattern.substr(token.pos + token.length);
  const std::string folderText = pattern.substr(0, nameStart);
  const std::filesystem::path folder = folderText.empty() ? "." : folderText;
  for (std::filesystem::directory_iterator it(folder, ec), end; !ec && it != end;
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() + suffix.size() || name.compare(0, prefix.size(), prefix) ||
        name.compare(name.size() - suffix.size(), suffix.size(), suffix)) {
      continue;
    }
    const std::string middle =
        name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
    int frame = 0;
    const auto result = std::from_chars(middle.data(), middle.data() + middle.size(), frame);
    if (result.ec != std::errc() || result.ptr != middle.data() + middle.size() ||
        formatFrameNumber(frame, token.width) != middle) {
      continue;
    }
    std::error_code fileEc;
    if (it->is_regular_file(fileEc)) {
      found.emplace(frame, folderText + name);
    }
  }
  return found;
}

}  // namespace io

std::vector<int> parseFrameRange(const std::string& text) {
  if (trimSpaces(text).empty()) {
    DS_THROW(kUsage, "empty frame range '", text, "'; ", kRangeHelp);
  }
  std::vector<int> frames;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    const std::string item = trimSpaces(
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    appendItem(item, text, frames);
    if (comma == std::string::npos) {
      break;
    }
    start = comma + 1;
  }
  return withoutRepeats(std::move(frames));
}

std::string formatFrameRange(const std::vector<int>& frames) {
  std::string text;
  const auto append = [&text](const std::string& item) {
    if (!text.empty()) {
      text += ',';
    }
    text += item;
  };
  std::size_t i = 0;
  while (i < frames.size()) {
    // The longest run from i with a constant positive step.
    std::size_t end = i + 1;
    std::int64_t step = 0;
    if (end < frames.size()) {
      step = static_cast<std::int64_t>(frames[end]) - frames[i];
    }
    if (step > 0) {
      while (end < frames.size() &&
             static_cast<std::int64_t>(frames[end]) - frames[end - 1] == step) {
        ++end;
      }
    } else {
      end = i + 1;
    }
    const std::size_t length = end - i;
    if (length >= 3 || (length == 2 && step == 1)) {
      std::string item = std::to_string(frames[i]) + "-" + std::to_string(frames[end - 1]);
      if (step != 1) {
        item += "x" + std::to_string(step);
      }
      append(item);
      i = end;
    } else {
      // A lone frame, or a pair with a gap: "1,5" reads better than "1-5x4".
      append(std::to_string(frames[i]));
      ++i;
    }
  }
  return text;
}

bool hasFramePattern(const std::string& pattern) {
  return !io::findFrameTokens(pattern).empty();
}

std::size_t framePatternPosition(const std::string& pattern) {
  const std::vector<io::FrameToken> tokens = io::findFrameTokens(pattern);
  return tokens.empty() ? std::string::npos : tokens.front().pos;
}

std::string sequenceStem(const std::string& pattern) {
  const std::size_t slash = pattern.find_last_of('/');
  std::string name = slash == std::string::npos ? pattern : pattern.substr(slash + 1);
  name = name.substr(0, framePatternPosition(name));
  while (!name.empty() && (name.back() == '.' || name.back() == '_' || name.back() == '-')) {
    name.pop_back();
  }
  return name.empty() ? std::string("bake") : name;
}

std::string expandFramePattern(const std::string& pattern, int frame) {
  const std::vector<io::FrameToken> tokens = io::findFrameTokens(pattern);
  if (tokens.empty()) {
    DS_THROW(kUsage, "'", pattern,
             "' has no frame token; put one in the file name: ####, %04d or $F4");
  }
  if (tokens.size() > 1) {
    DS_THROW(kUsage, "'", pattern, "' has ", tokens.size(),
             " frame tokens; use exactly one (####, %04d or $F4)");
  }
  const io::FrameToken& token = tokens.front();
  const std::size_t slash = pattern.find_last_of('/');
  if (slash != std::string::npos && token.pos < slash) {
    DS_THROW(kUsage, "'", pattern,
             "': the frame token is in a folder name (a folder per frame); put it in the file "
             "name, e.g. out/cloth.####.exr");
  }
  return pattern.substr(0, token.pos) + io::formatFrameNumber(frame, token.width) +
         pattern.substr(token.pos + token.length);
}

namespace {

/// `path` with its folder resolved (links, `..`, `.`) as far as it exists, for comparing names.
class PathResolver {
 public:
  std::string resolve(const std::string& path) {
    std::error_code absoluteError;
    const std::filesystem::path full = std::filesystem::absolute(path, absoluteError);
    const std::string folder = full.parent_path().string();
    auto found = mFolders.find(folder);
    if (found == mFolders.end()) {
      std::error_code ec;
      std::filesystem::path resolved = std::filesystem::weakly_canonical(folder, ec);
      found = mFolders.emplace(folder, ec ? folder : resolved.string()).first;
    }
    return (std::filesystem::path(found->second) / full.filename()).lexically_normal().string();
  }

 private:
  std::map<std::string, std::string> mFolders;
};

std::vector<std::string> namesOf(const NamedPath& named, const std::vector<int>& frames) {
  if (!named.sequence) {
    return {named.path};
  }
  std::vector<std::string> names;
  names.reserve(frames.size());
  for (int frame : frames) {
    names.push_back(expandFramePattern(named.path, frame));
  }
  return names;
}

/// A file by its identity: device and inode after following links, so a link, a hard link or
/// a path through a linked folder is the file it reaches.
using FileId = std::pair<std::uint64_t, std::uint64_t>;

bool fileIdOf(const std::string& path, FileId& id) {
  struct stat status {};
  if (::stat(path.c_str(), &status) != 0) {
    return false;
  }
  id = {static_cast<std::uint64_t>(status.st_dev), static_cast<std::uint64_t>(status.st_ino)};
  return true;
}

/// The files an input may be read from: the file, or every file of a sequence that exists
/// (whatever its frame: a bake reads driver frames before --frames as history, a cache may be
/// read at an offset), plus the sequence's names over `frames`.
std::vector<std::string> inputFilesOf(const NamedPath& input, const std::vector<int>& frames) {
  std::vector<std::string> names = namesOf(input, frames);
  if (input.sequence) {
    std::error_code ec;
    for (auto& [frame, file] : io::listSequenceFiles(input.path, ec)) {
      names.push_back(std::move(file));
    }
  }
  return names;
}

[[noreturn]] void throwOverwrite(const NamedPath& output, const NamedPath& input,
                                 const std::string& name, const std::string& reached) {
  DS_THROW(kUsage, output.option, " '", output.path, "' would overwrite the input ", input.option,
           " '", input.path, "' (file '", name, "'", reached, "); write the output elsewhere");
}

}  // namespace

void checkDistinctPaths(const std::vector<NamedPath>& outputs, const std::vector<int>& frames,
                        const std::vector<NamedPath>& inputs) {
  PathResolver resolver;
  std::map<std::string, const NamedPath*> written;
  // The outputs that exist already, by identity: writing one replaces the file it reaches.
  std::map<FileId, std::pair<const NamedPath*, std::string>> existing;
  for (const NamedPath& output : outputs) {
    for (const std::string& name : namesOf(output, frames)) {
      const auto [at, inserted] = written.emplace(resolver.resolve(name), &output);
      if (!inserted && at->second != &output) {
        DS_THROW(kUsage, at->second->option, " '", at->second->path, "' and ", output.option, " '",
                 output.path, "' both name the file '", name, "'; give each output its own name");
      }
      FileId id;
      if (fileIdOf(name, id)) {
        existing.emplace(id, std::make_pair(&output, name));
      }
    }
  }
  for (const NamedPath& input : inputs) {
    for (const std::string& name : inputFilesOf(input, frames)) {
      const auto at = written.find(resolver.resolve(name));
      if (at != written.end()) {
        throwOverwrite(*at->second, input, name, "");
      }
      FileId id;
      const auto same = fileIdOf(name, id) ? existing.find(id) : existing.end();
      if (same != existing.end()) {
        throwOverwrite(*same->second.first, input, name,
                       ", the same file as '" + same->second.second + "' through a link");
      }
    }
  }
}

}  // namespace drivenshape
