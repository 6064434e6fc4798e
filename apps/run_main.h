// SPDX-License-Identifier: Apache-2.0
#pragma once

// The one `main` of every tool in apps/: runs the tool's body with its command-line arguments
// and turns what escapes it into the documented exit codes (docs/commands.md), with one line on
// stderr naming the tool: a drivenshape::Error exits with its code, running out of memory and
// any other exception with kInternal (1). Messages are printed with unprintable bytes escaped
// and very long ones shortened (a bad input's raw bytes or a path of thousands of bytes).
// SIGXFSZ is ignored: a write past the file-size limit (`ulimit -f`) then fails with EFBIG like
// a full disk, and the writer's error path removes its temporary file and exits 4 instead of
// the process dying with the file left behind.

#include <csignal>
#include <cstdio>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include <drivenshape/error.h>

#include "text.h"

namespace drivenshape::cli {

template <typename Body>
int runMain(const char* tool, int argc, char** argv, Body&& body) {
  std::signal(SIGXFSZ, SIG_IGN);
  try {
    return body(std::vector<std::string>(argv + 1, argv + argc));
  } catch (const Error& error) {
    std::fprintf(stderr, "%s: %s: %s\n", tool, errorCodeName(error.code()),
                 printableText(error.what()).c_str());
    return static_cast<int>(error.code());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr,
                 "%s: internal error: out of memory; work on fewer frames at once (--batch, "
                 "--chunk-size) or on a machine with more memory\n",
                 tool);
    return static_cast<int>(ErrorCode::kInternal);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "%s: internal error: %s\n", tool, printableText(error.what()).c_str());
    return static_cast<int>(ErrorCode::kInternal);
  }
}

}  // namespace drivenshape::cli
