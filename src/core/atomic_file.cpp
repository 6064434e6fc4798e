#include "atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>

#include <drivenshape/error.h>

namespace drivenshape {
namespace {

std::string folderOf(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  return parent.empty() ? std::string(".") : parent.string();
}

/// What every temporary name of `finalPath` starts with: `.<name>.tmp-` (then `<pid>-<n>`).
std::string tempPrefixFor(const std::string& finalPath) {
  return "." + std::filesystem::path(finalPath).filename().string() + ".tmp-";
}

std::string tempPathFor(const std::string& finalPath) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path target(finalPath);
  const std::string name =
      tempPrefixFor(finalPath) + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  return (target.parent_path() / name).string();
}

}  // namespace

void checkOutputFolderWritable(const std::string& path) {
  const std::string folder = folderOf(path);
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec)) {
    DS_THROW(kOutput, "output folder '", folder, "' (for ", path,
             ") does not exist; create it first");
  }
  if (::access(folder.c_str(), W_OK) != 0) {
    DS_THROW(kOutput, "output folder '", folder, "' (for ", path,
             ") is not writable: ", std::strerror(errno));
  }
}

AtomicFile::AtomicFile(std::string finalPath)
    : mFinalPath(std::move(finalPath)), mTempPath(tempPathFor(mFinalPath)) {
  checkOutputFolderWritable(mFinalPath);
}

AtomicFile::~AtomicFile() {
  if (!mCommitted) {
    std::remove(mTempPath.c_str());
  }
}

void AtomicFile::commit(bool syncToDisk) {
  if (syncToDisk) {
    sync();
  }
  if (std::rename(mTempPath.c_str(), mFinalPath.c_str()) != 0) {
    const int renameErrno = errno;
    std::remove(mTempPath.c_str());
    DS_THROW(kOutput, "cannot move the finished file into place at '", mFinalPath,
             "': ", std::strerror(renameErrno));
  }
  mCommitted = true;
}

void AtomicFile::sync() {
  const int fd = ::open(mTempPath.c_str(), O_RDONLY);
  if (fd < 0) {
    DS_THROW(kOutput, "cannot reopen temporary file '", mTempPath, "' for ", mFinalPath, ": ",
             std::strerror(errno));
  }
  const int syncResult = ::fsync(fd);
  const int syncErrno = errno;
  ::close(fd);
  if (syncResult != 0) {
    std::remove(mTempPath.c_str());
    DS_THROW(kOutput, "cannot flush '", mFinalPath, "' to disk: ", std::strerror(syncErrno));
  }
}

std::string readWholeFile(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    DS_THROW(kInput, "cannot read ", what, " '", path, "': it is a folder, not a file");
  }
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) {
    DS_THROW(kInput, "cannot read ", what, " '", path, "': ", std::strerror(errno));
  }
  std::string bytes;
  char buffer[1 << 16];
  std::size_t got;
  while ((got = std::fread(buffer, 1, sizeof(buffer), file)) > 0) {
    bytes.append(buffer, got);
  }
  const bool failed = std::ferror(file) != 0;
  const int readErrno = errno;
  std::fclose(file);
  if (failed) {
    DS_THROW(kInput, "cannot read ", what, " '", path, "': ", std::strerror(readErrno));
  }
  return bytes;
}

int removeStaleTempFiles(const std::vector<std::string>& finalPaths) {
  // One listing per folder: the temporary name of <name> starts with ".<name>.tmp-".
  std::map<std::string, std::set<std::string>> wanted;
  for (const std::string& path : finalPaths) {
    wanted[folderOf(path)].insert(tempPrefixFor(path));
  }
  int removed = 0;
  for (const auto& [folder, prefixes] : wanted) {
    std::error_code ec;
    for (std::filesystem::directory_iterator it(folder, ec), end; !ec && it != end;
         it.increment(ec)) {
      const std::string name = it->path().filename().string();
      const std::size_t marker = name.rfind(".tmp-");
      if (name.empty() || name[0] != '.' || marker == std::string::npos ||
          prefixes.count(name.substr(0, marker + 5)) == 0) {
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

void writeFileAtomically(const std::string& path, const std::string& bytes) {
  AtomicFile file(path);
  std::FILE* stream = std::fopen(file.tempPath().c_str(), "wb");
  if (stream == nullptr) {
    DS_THROW(kOutput, "cannot create '", path, "': ", std::strerror(errno));
  }
  const std::size_t written = std::fwrite(bytes.data(), 1, bytes.size(), stream);
  const bool flushed = std::fflush(stream) == 0;
  const int writeErrno = errno;
  std::fclose(stream);
  if (written != bytes.size() || !flushed) {
    DS_THROW(kOutput, "cannot write '", path, "' (", bytes.size(),
             " bytes): ", std::strerror(writeErrno), "; is the disk full?");
  }
  file.commit();
}

}  // namespace drivenshape
