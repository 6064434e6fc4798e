// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <exception>
#include <memory>
#include <sstream>
#include <string>

namespace drivenshape {

/// What went wrong, as a class of failure. The values are the process exit codes of the
/// `drivenshape` command line (documented in docs/commands.md), so keep them stable.
enum class ErrorCode : int {
  kInternal = 1,    ///< a bug or an unexpected condition inside the tool
  kUsage = 2,       ///< bad command line: unknown flag, missing value, empty frame range
  kInput = 3,       ///< an input file is missing, unreadable, malformed or does not match
  kOutput = 4,      ///< an output could not be written (folder missing, read-only, disk full)
  kDevice = 5,      ///< OpenCL: no device, build failure, out of device memory
  kNumerical = 6,   ///< a solve failed its checks (NaN in data, constraint violation)
  kInterrupted = 7  ///< stopped by SIGINT/SIGTERM between frames; finished frames are kept
};

/// The one exception type of the library: a code plus a message that says what was wrong,
/// where (file, frame, vertex, flag) and, where possible, what to do. Cheap to copy.
class Error : public std::exception {
 public:
  Error(ErrorCode code, std::string message)
      : mCode(code), mMessage(std::make_shared<const std::string>(std::move(message))) {}

  ErrorCode code() const noexcept { return mCode; }
  const char* what() const noexcept override { return mMessage->c_str(); }

 private:
  ErrorCode mCode;
  std::shared_ptr<const std::string> mMessage;
};

/// Short name of a code ("input error", ...), for the first word of a message.
const char* errorCodeName(ErrorCode code);

namespace detail {
template <typename... Args>
std::string concat(const Args&... args) {
  std::ostringstream stream;
  (stream << ... << args);
  return stream.str();
}
}  // namespace detail

/// Throws drivenshape::Error with the message built from the stream-able arguments.
/// Example: DS_THROW(kInput, path, ": frame ", frame, " is missing; the cache has ", n);
#define DS_THROW(code, ...)                                  \
  throw ::drivenshape::Error(::drivenshape::ErrorCode::code, \
                             ::drivenshape::detail::concat(__VA_ARGS__))

}  // namespace drivenshape
