#pragma once

#include <string>
#include <vector>

namespace drivenshape {

/// Writes a file so that readers only ever see the old file or the whole new one.
///
/// The content goes to a temporary file in the destination folder (same file system),
/// named `.<name>.tmp-<pid>-<n>`; commit() flushes it and renames it over the target.
/// If the object is destroyed without commit() (an exception, a failed write) the
/// temporary file is removed, so no partial output is ever left behind.
///
///     AtomicFile file("out/cloth.1001.exr");
///     writeSomething(file.tempPath());   // any writer that takes a path
///     file.commit();
class AtomicFile {
 public:
  /// Throws Error(kOutput) naming the folder when it does not exist or is not writable.
  explicit AtomicFile(std::string finalPath);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  const std::string& tempPath() const { return mTempPath; }
  const std::string& finalPath() const { return mFinalPath; }
  /// Renames the finished file into place, after an fsync when `syncToDisk`; throws
  /// Error(kOutput) on failure (and removes the temp file). Without the fsync readers still see
  /// the old file or the whole new one, but after a power loss or kernel crash the new file can
  /// be empty or short (a resumed bake's --skip-existing check takes it for incomplete).
  void commit(bool syncToDisk = true);

 private:
  void sync();

  std::string mFinalPath;
  std::string mTempPath;
  bool mCommitted = false;
};

/// Removes the temporary files (`.<name>.tmp-*`) that killed writers left for `finalPaths`,
/// e.g. the frames a resumed farm task owns, and returns how many it removed. Only call it for
/// files no other live process is writing.
int removeStaleTempFiles(const std::vector<std::string>& finalPaths);

/// Writes `bytes` to `path` atomically (see AtomicFile).
void writeFileAtomically(const std::string& path, const std::string& bytes);

/// The whole content of the file at `path`. Throws Error(kInput) "cannot read <what> '<path>':
/// <reason>" when it is missing, a folder or unreadable; `what` names the kind of file
/// ("database", "OBJ", "binding mask", ...).
std::string readWholeFile(const std::string& path, const std::string& what);

/// Throws Error(kOutput) naming the folder of `path` and the reason when a file cannot be
/// created there. Call before long work so a bad -o fails in the first second.
void checkOutputFolderWritable(const std::string& path);

}  // namespace drivenshape
