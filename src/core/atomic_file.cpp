// SPDX-License-Identifier: Apache-2.0
#include "atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <random>
#include <set>
#include <streambuf>

#include <drivenshape/error.h>

#include "hash.h"
#include "text.h"

namespace drivenshape {
namespace {

constexpr const char* kTempMarker = ".tmp-";
constexpr std::size_t kRandomDigits = 16;
/// A temporary name is `.` + the (maybe shortened) name + kTempMarker + the random digits.
constexpr std::size_t kTempExtraBytes = 1 + 5 + kRandomDigits;
/// Paths in messages are cut to this many bytes (a path can be thousands of bytes long).
constexpr std::size_t kPathInMessage = 240;

std::string shown(const std::string& path) {
  return printableText(path, kPathInMessage);
}

/// Throws Error(kOutput) when `path` is past the system's PATH_MAX.
void checkPathLength(const std::string& path) {
  if (path.size() >= PATH_MAX) {
    DS_THROW(kOutput, "output path '", shown(path), "' is ", path.size(),
             " bytes; the system allows at most ", PATH_MAX - 1,
             " bytes per path (PATH_MAX): choose a shorter path");
  }
}

std::string folderOf(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  return parent.empty() ? std::string(".") : parent.string();
}

/// The longest file name the folder's file system takes (255 on Linux file systems).
std::size_t nameLimitOf(const std::string& folder) {
  errno = 0;
  const long limit = ::pathconf(folder.c_str(), _PC_NAME_MAX);
  return limit > 0 ? static_cast<std::size_t>(limit) : 255;
}

/// What every temporary name of `finalPath` starts with: `.<name>.tmp-`. Where the whole
/// temporary name would pass the folder's name limit, the name is cut short and ends in `~`
/// and 16 hex digits of the hash of the whole name, so two long names that share their first
/// bytes (frames of one sequence) still have prefixes of their own.
std::string tempPrefixFor(const std::string& finalPath, std::size_t nameLimit) {
  std::string name = std::filesystem::path(finalPath).filename().string();
  if (name.size() + kTempExtraBytes > nameLimit) {
    const std::string tag = "~" + hashToHex(Hasher().addString(name).value());
    const std::size_t room =
        nameLimit > kTempExtraBytes + tag.size() ? nameLimit - kTempExtraBytes - tag.size() : 0;
    name.resize(room);
    name += tag;
  }
  return "." + name + kTempMarker;
}

/// Whether `name` is a temporary name with `prefix` exactly: the prefix, then 16 lowercase hex
/// digits and nothing else (a user's `.x.tmp-notes` is not one).
bool isTempName(const std::string& name, const std::string& prefix) {
  if (name.size() != prefix.size() + kRandomDigits || name.compare(0, prefix.size(), prefix) != 0) {
    return false;
  }
  for (std::size_t i = prefix.size(); i < name.size(); ++i) {
    const char ch = name[i];
    if (!((ch >= '0' && ch <= '9') || (ch >= 'a' && ch <= 'f'))) {
      return false;
    }
  }
  return true;
}

std::string randomDigits() {
  static thread_local std::mt19937_64 generator = [] {
    std::random_device device;  // the kernel's random source (getrandom)
    std::seed_seq seed{device(), device(), device(), device()};
    return std::mt19937_64(seed);
  }();
  static const char kHex[] = "0123456789abcdef";
  std::string digits(kRandomDigits, '0');
  std::uint64_t bits = generator();
  for (char& digit : digits) {
    digit = kHex[bits & 15u];
    bits >>= 4;
  }
  return digits;
}

/// Throws Error(kOutput) when the name of `path` is longer than its folder allows.
void checkNameLength(const std::string& path, const std::string& folder) {
  const std::string name = std::filesystem::path(path).filename().string();
  const std::size_t limit = nameLimitOf(folder);
  if (name.size() > limit) {
    DS_THROW(kOutput, "output name '", shown(name), "' is ", name.size(),
             " bytes; the file system of folder '", shown(folder), "' allows at most ", limit,
             " bytes per name: choose a shorter name");
  }
}

}  // namespace

/// An unbuffered std::streambuf over a C stream (which buffers): what AtomicFile::stream()
/// writes through, seekable for writers that patch an offset table afterwards.
class AtomicFile::Buffer : public std::streambuf {
 public:
  explicit Buffer(std::FILE* file) : mFile(file) {}

 protected:
  int_type overflow(int_type c) override {
    if (traits_type::eq_int_type(c, traits_type::eof())) {
      return traits_type::not_eof(c);
    }
    return std::fputc(c, mFile) == EOF ? traits_type::eof() : c;
  }
  std::streamsize xsputn(const char* data, std::streamsize count) override {
    return static_cast<std::streamsize>(
        std::fwrite(data, 1, static_cast<std::size_t>(count), mFile));
  }
  pos_type seekoff(off_type offset, std::ios_base::seekdir dir, std::ios_base::openmode) override {
    const int whence = dir == std::ios_base::beg   ? SEEK_SET
                       : dir == std::ios_base::cur ? SEEK_CUR
                                                   : SEEK_END;
    if (::fseeko(mFile, static_cast<off_t>(offset), whence) != 0) {
      return pos_type(off_type(-1));
    }
    return pos_type(static_cast<off_type>(::ftello(mFile)));
  }
  pos_type seekpos(pos_type position, std::ios_base::openmode mode) override {
    return seekoff(off_type(position), std::ios_base::beg, mode);
  }
  int sync() override { return std::fflush(mFile) == 0 ? 0 : -1; }

 private:
  std::FILE* mFile;
};

void checkOutputFolderWritable(const std::string& path) {
  const std::string folder = folderOf(path);
  checkPathLength(path);
  struct stat status {};
  if (::stat(path.c_str(), &status) == 0 && S_ISDIR(status.st_mode)) {
    DS_THROW(kOutput, "output '", shown(path), "' is a folder; name a file (in it, or beside it)");
  }
  if (::stat(folder.c_str(), &status) != 0) {
    const int error = errno;
    if (error == ENOENT) {
      DS_THROW(kOutput, "output folder '", shown(folder), "' (for ", shown(path),
               ") does not exist; create it first");
    }
    DS_THROW(kOutput, "output folder '", shown(folder), "' (for ", shown(path),
             ") cannot be used: ", std::strerror(error));
  }
  if (!S_ISDIR(status.st_mode)) {
    DS_THROW(kOutput, "output folder '", shown(folder), "' (for ", shown(path),
             ") is not a folder");
  }
  if (::access(folder.c_str(), W_OK) != 0) {
    DS_THROW(kOutput, "output folder '", shown(folder), "' (for ", shown(path),
             ") is not writable: ", std::strerror(errno));
  }
  checkNameLength(path, folder);
}

std::vector<std::string> missingOutputFolders(const std::string& path) {
  std::vector<std::string> missing;
  std::filesystem::path folder = folderOf(path);
  struct stat status {};
  while (::stat(folder.c_str(), &status) != 0 && errno == ENOENT && folder.has_relative_path()) {
    missing.insert(missing.begin(), folder.string());
    folder = folder.has_parent_path() ? folder.parent_path() : std::filesystem::path(".");
  }
  if (missing.empty()) {
    checkOutputFolderWritable(path);
    return missing;
  }
  // The nearest folder that exists must take the new ones (checked with a file name in it).
  checkOutputFolderWritable((folder / "x").string());
  checkPathLength(path);
  return missing;
}

std::vector<std::string> createOutputFolders(const std::string& path) {
  std::vector<std::string> created;
  for (const std::string& folder : missingOutputFolders(path)) {
    if (::mkdir(folder.c_str(), 0777) == 0) {
      created.push_back(folder);
    } else if (errno != EEXIST) {
      DS_THROW(kOutput, "cannot create output folder '", shown(folder), "' (for ", shown(path),
               "): ", std::strerror(errno));
    }
  }
  checkOutputFolderWritable(path);
  return created;
}

AtomicFile::AtomicFile(std::string finalPath) : mFinalPath(std::move(finalPath)) {
  checkOutputFolderWritable(mFinalPath);
  const std::string folder = folderOf(mFinalPath);
  const std::filesystem::path parent = std::filesystem::path(mFinalPath).parent_path();
  const std::string prefix = tempPrefixFor(mFinalPath, nameLimitOf(folder));
  // A name that exists (a file, or a link planted by someone else) is never opened: draw again.
  for (int attempt = 0; attempt < 64 && mFile == nullptr; ++attempt) {
    const std::string candidate = (parent / (prefix + randomDigits())).string();
    const int fd =
        ::open(candidate.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
    if (fd < 0) {
      if (errno == EEXIST) {
        continue;
      }
      DS_THROW(kOutput, "cannot create '", shown(mFinalPath), "' (temporary file '",
               shown(candidate), "'): ", std::strerror(errno));
    }
    mFile = ::fdopen(fd, "wb");
    if (mFile == nullptr) {
      const int error = errno;
      ::close(fd);
      std::remove(candidate.c_str());
      DS_THROW(kOutput, "cannot create '", shown(mFinalPath), "': ", std::strerror(error));
    }
    mTempPath = candidate;
  }
  if (mFile == nullptr) {
    DS_THROW(kOutput, "cannot create '", shown(mFinalPath),
             "': every temporary name tried in its folder exists already");
  }
}

AtomicFile::~AtomicFile() {
  mStream.reset();
  mBuffer.reset();
  if (mFile != nullptr) {
    std::fclose(mFile);
  }
  if (!mCommitted && !mTempPath.empty()) {
    std::remove(mTempPath.c_str());
  }
}

std::ostream& AtomicFile::stream() {
  if (!mStream) {
    mBuffer = std::make_unique<Buffer>(mFile);
    mStream = std::make_unique<std::ostream>(mBuffer.get());
  }
  return *mStream;
}

void AtomicFile::commit(bool syncToDisk) {
  finish(syncToDisk);
  publish();
}

void AtomicFile::finish(bool syncToDisk) {
  if (mFile == nullptr || mFinished) {
    DS_THROW(kInternal, "AtomicFile '", shown(mFinalPath), "' committed twice");
  }
  errno = 0;
  const bool streamFailed = mStream && mStream->fail();
  bool failed = streamFailed || std::fflush(mFile) != 0 || std::ferror(mFile) != 0;
  int error = errno;
  if (!failed && syncToDisk && ::fsync(::fileno(mFile)) != 0) {
    failed = true;
    error = errno;
  }
  mStream.reset();
  mBuffer.reset();
  const bool closeFailed = std::fclose(mFile) != 0;
  if (closeFailed && !failed) {
    failed = true;
    error = errno;
  }
  mFile = nullptr;
  mFinished = true;
  if (failed) {
    std::remove(mTempPath.c_str());
    mTempPath.clear();
    DS_THROW(kOutput, "cannot write '", shown(mFinalPath),
             "': ", std::strerror(error != 0 ? error : EIO), "; is the disk full?");
  }
}

void AtomicFile::publish() {
  if (!mFinished || mCommitted || mTempPath.empty()) {
    DS_THROW(kInternal, "AtomicFile '", shown(mFinalPath), "' published before finish()");
  }
  if (std::rename(mTempPath.c_str(), mFinalPath.c_str()) != 0) {
    const int renameErrno = errno;
    std::remove(mTempPath.c_str());
    mTempPath.clear();
    DS_THROW(kOutput, "cannot move the finished file into place at '", shown(mFinalPath),
             "': ", std::strerror(renameErrno));
  }
  mCommitted = true;
}

void requireRegularFile(const std::string& path, const std::string& what) {
  struct stat status {};
  if (::stat(path.c_str(), &status) != 0) {
    DS_THROW(kInput, "cannot read ", what, " '", shown(path), "': ", std::strerror(errno));
  }
  if (S_ISDIR(status.st_mode)) {
    DS_THROW(kInput, "cannot read ", what, " '", shown(path), "': it is a folder, not a file");
  }
  if (!S_ISREG(status.st_mode)) {
    const char* kind = S_ISFIFO(status.st_mode)   ? "a FIFO (named pipe)"
                       : S_ISSOCK(status.st_mode) ? "a socket"
                       : S_ISCHR(status.st_mode)  ? "a character device"
                       : S_ISBLK(status.st_mode)  ? "a block device"
                                                  : "not a regular file";
    DS_THROW(kInput, "cannot read ", what, " '", shown(path), "': it is ", kind,
             ", not a regular file; copy the data to a file first");
  }
}

std::string readWholeFile(const std::string& path, const std::string& what) {
  requireRegularFile(path, what);
  // O_NONBLOCK: should the name have become a FIFO since the check, the open does not hang.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    DS_THROW(kInput, "cannot read ", what, " '", shown(path), "': ", std::strerror(errno));
  }
  struct stat status {};
  if (::fstat(fd, &status) != 0 || !S_ISREG(status.st_mode)) {
    ::close(fd);
    DS_THROW(kInput, "cannot read ", what, " '", shown(path), "': not a regular file");
  }
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  std::string bytes;
  char buffer[1 << 16];
  for (;;) {
    const ssize_t got = ::read(fd, buffer, sizeof(buffer));
    if (got > 0) {
      bytes.append(buffer, static_cast<std::size_t>(got));
    } else if (got == 0) {
      break;
    } else if (errno != EINTR) {
      const int readErrno = errno;
      ::close(fd);
      DS_THROW(kInput, "cannot read ", what, " '", shown(path), "': ", std::strerror(readErrno));
    }
  }
  ::close(fd);
  return bytes;
}

int removeStaleTempFiles(const std::vector<std::string>& finalPaths) {
  // One listing per folder: the temporary name of <name> starts with ".<name>.tmp-".
  std::map<std::string, std::set<std::string>> wanted;
  for (const std::string& path : finalPaths) {
    const std::string folder = folderOf(path);
    wanted[folder].insert(tempPrefixFor(path, nameLimitOf(folder)));
  }
  int removed = 0;
  for (const auto& [folder, prefixes] : wanted) {
    std::error_code ec;
    for (std::filesystem::directory_iterator it(folder, ec), end; !ec && it != end;
         it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (name.size() <= kRandomDigits) {
        continue;
      }
      const auto prefix = prefixes.find(name.substr(0, name.size() - kRandomDigits));
      std::error_code typeError;
      if (prefix == prefixes.end() || !isTempName(name, *prefix) ||
          !it->is_regular_file(typeError)) {
        continue;
      }
      std::error_code removeError;
      if (std::filesystem::remove(it->path(), removeError)) {
        ++removed;
      }
    }
  }
  return removed;
}

namespace {

void writeBytes(AtomicFile& file, const std::string& bytes) {
  if (std::fwrite(bytes.data(), 1, bytes.size(), file.file()) != bytes.size()) {
    DS_THROW(kOutput, "cannot write '", shown(file.finalPath()), "' (", bytes.size(),
             " bytes): ", std::strerror(errno), "; is the disk full?");
  }
}

/// The file at a path that writeFilesTogether replaces: whether there was one, and a hard link
/// to it under a temporary name of that path (empty when there was none or the file system
/// makes no hard links), so that it can be put back.
struct Displaced {
  std::string finalPath;
  std::string keptPath;
  bool existed = false;
};

Displaced keepOldVersion(const std::string& finalPath) {
  Displaced displaced{finalPath, "", false};
  struct stat status {};
  if (::lstat(finalPath.c_str(), &status) != 0) {
    return displaced;
  }
  displaced.existed = true;
  const std::filesystem::path parent = std::filesystem::path(finalPath).parent_path();
  const std::string prefix = tempPrefixFor(finalPath, nameLimitOf(folderOf(finalPath)));
  for (int attempt = 0; attempt < 64; ++attempt) {
    const std::string candidate = (parent / (prefix + randomDigits())).string();
    if (::link(finalPath.c_str(), candidate.c_str()) == 0) {
      displaced.keptPath = candidate;
      break;
    }
    if (errno != EEXIST) {
      break;
    }
  }
  return displaced;
}

/// Puts back the old version of each of `moved` (or removes the new file where there was none)
/// and drops the kept links of the rest.
void restoreDisplaced(const std::vector<Displaced>& displaced, std::size_t moved) {
  for (std::size_t i = 0; i < displaced.size(); ++i) {
    const Displaced& d = displaced[i];
    if (i < moved && !d.keptPath.empty()) {
      std::rename(d.keptPath.c_str(), d.finalPath.c_str());
    } else if (i < moved && !d.existed) {
      std::remove(d.finalPath.c_str());
    } else if (!d.keptPath.empty()) {
      std::remove(d.keptPath.c_str());
    }
  }
}

}  // namespace

void writeFileAtomically(const std::string& path, const std::string& bytes) {
  AtomicFile file(path);
  writeBytes(file, bytes);
  file.commit();
}

void writeFilesTogether(const std::vector<std::pair<std::string, std::string>>& files) {
  // Every file complete under its temporary name first: a failure here leaves no file changed.
  std::vector<std::unique_ptr<AtomicFile>> temporaries;
  for (const auto& [path, bytes] : files) {
    temporaries.push_back(std::make_unique<AtomicFile>(path));
    writeBytes(*temporaries.back(), bytes);
    temporaries.back()->finish();
  }
  std::vector<Displaced> displaced;
  for (const auto& file : files) {
    displaced.push_back(keepOldVersion(file.first));
  }
  for (std::size_t i = 0; i < temporaries.size(); ++i) {
    try {
      temporaries[i]->publish();
    } catch (const Error&) {
      restoreDisplaced(displaced, i);
      throw;
    }
  }
  restoreDisplaced(displaced, 0);  // all in place: only the kept links go
}

}  // namespace drivenshape
