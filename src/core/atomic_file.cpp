#include <drivenshape/atomic_file.h>

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include <drivenshape/error.h>

namespace drivenshape {
namespace {

std::string folderOf(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  return parent.empty() ? std::string(".") : parent.string();
}

std::string tempPathFor(const std::string& finalPath) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path target(finalPath);
  const std::string name = "." + target.filename().string() + ".tmp-" + std::to_string(::getpid()) +
                           "-" + std::to_string(counter++);
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
