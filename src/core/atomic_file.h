// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstdio>
#include <memory>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

namespace drivenshape {

/// Writes a file so that readers only ever see the old file or the whole new one, and so that
/// nothing planted in the destination folder can redirect the write.
///
/// The constructor creates a temporary file in the destination folder (same file system) under
/// an unpredictable name, `.<name>.tmp-<16 random hex digits>`, exclusively (`O_CREAT | O_EXCL |
/// O_NOFOLLOW`): an existing file or symbolic link at that name is never opened, a new name is
/// drawn instead. The content is written through stream() or file(), i.e. through the file
/// descriptor that was created, never by reopening the name. commit() flushes it and renames it
/// over the target; rename replaces a symbolic link at the target, it never follows it. If the
/// object is destroyed without commit() (an exception, a failed write) the temporary file is
/// removed, so no partial output is ever left behind. A destination name so long that the
/// temporary name would pass the folder's name limit is cut short and tagged with a hash of
/// the whole name (`.<start of name>~<16 hex digits>.tmp-<16 random hex digits>`), so every
/// destination has a temporary prefix of its own.
///
///     AtomicFile file("out/cloth.1001.exr");
///     file.stream() << bytes;
///     file.commit();
class AtomicFile {
 public:
  /// Throws Error(kOutput) naming the folder when it does not exist or is not writable, and
  /// naming the limit when the file's name is longer than the file system allows.
  explicit AtomicFile(std::string finalPath);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /// The temporary file's path, for messages only: write through stream() or file().
  const std::string& tempPath() const { return mTempPath; }
  const std::string& finalPath() const { return mFinalPath; }
  /// The temporary file as a binary stream (seekable). Use either stream() or file().
  std::ostream& stream();
  /// The temporary file as a C stream. Use either stream() or file().
  std::FILE* file() { return mFile; }
  /// Renames the finished file into place, after an fsync when `syncToDisk`; throws
  /// Error(kOutput) on failure (and removes the temp file). Without the fsync readers still see
  /// the old file or the whole new one, but after a power loss or kernel crash the new file can
  /// be empty or short (a resumed bake's --skip-existing check takes it for incomplete).
  void commit(bool syncToDisk = true);
  /// commit() in two steps, for files that must change together (writeFilesTogether): finish()
  /// flushes, syncs (when `syncToDisk`) and closes the temporary file, throwing Error(kOutput)
  /// as commit() does; publish() then renames it into place.
  void finish(bool syncToDisk = true);
  void publish();

 private:
  class Buffer;

  std::string mFinalPath;
  std::string mTempPath;
  std::FILE* mFile = nullptr;
  std::unique_ptr<Buffer> mBuffer;
  std::unique_ptr<std::ostream> mStream;
  bool mFinished = false;
  bool mCommitted = false;
};

/// Removes the temporary files that killed writers left for `finalPaths` (regular files named
/// exactly as AtomicFile names them: the prefix of that final path, then 16 lowercase hex
/// digits), e.g. the frames a resumed farm task owns, and returns how many it removed. Files of
/// other final paths (another task's frames, however long their names) and other names are
/// left alone. Only call it for files no other live process is writing.
int removeStaleTempFiles(const std::vector<std::string>& finalPaths);

/// Writes `bytes` to `path` atomically (see AtomicFile).
void writeFileAtomically(const std::string& path, const std::string& bytes);

/// Writes files that belong together (path, bytes), e.g. a job template and its parameters
/// file, so that they change as a pair: each is written to its temporary file (AtomicFile) and
/// none is renamed into place before all are complete. On any failure (a full disk, the
/// file-size limit, a rename that fails) nothing this call made is left: the temporary files are
/// removed, and a file already renamed is put back as it was (its old version is kept as a hard
/// link until every rename has succeeded) or removed when it is new. Throws Error(kOutput) naming
/// the file.
void writeFilesTogether(const std::vector<std::pair<std::string, std::string>>& files);

/// The whole content of the file at `path`. Throws Error(kInput) "cannot read <what> '<path>':
/// <reason>" when it is missing, a folder, not a regular file (a FIFO, a device) or unreadable;
/// `what` names the kind of file ("database", "OBJ", "binding mask", ...).
std::string readWholeFile(const std::string& path, const std::string& what);

/// Throws Error(kInput) "cannot read <what> '<path>': <reason>" unless `path` names a regular
/// file (or a link to one) that exists: a folder, a FIFO, a socket or a device is refused before
/// anything opens it (opening a FIFO would block until a writer comes).
void requireRegularFile(const std::string& path, const std::string& what);

/// Throws Error(kOutput) naming the folder of `path` and the reason when a file cannot be
/// created there (missing, not a folder, not writable, a path or a name past the system's
/// limits), or when `path` itself is a folder. Call before long work so a bad -o fails in the
/// first second.
void checkOutputFolderWritable(const std::string& path);

/// The folders above the output `path` that do not exist yet, outermost first (empty when its
/// folder exists). Throws Error(kOutput) as checkOutputFolderWritable does, and naming the
/// nearest folder that exists when that one is not a writable folder, so a command can refuse
/// a bad -o before long work without creating anything.
std::vector<std::string> missingOutputFolders(const std::string& path);

/// Creates the folders missingOutputFolders(path) names, outermost first, like `mkdir -p`
/// (another process creating one at the same moment, e.g. a farm task beside this one, is
/// fine), and returns the ones this call created. Throws Error(kOutput) naming the folder that
/// could not be created.
std::vector<std::string> createOutputFolders(const std::string& path);

}  // namespace drivenshape
