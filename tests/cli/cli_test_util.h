#pragma once
// Helpers of the command-line tests (test_cli, test_eval): run the real `drivenshape` binary
// as a separate process with its output captured, and find the bundled sample.

#include <string>
#include <vector>

#include "test_support.h"

namespace drivenshape::testing {

/// What one run of the command gave: its exit code (-1 when it did not exit normally) and the
/// text it wrote to stdout and stderr.
struct CliRun {
  int code = -1;
  std::string out;
  std::string err;
};

/// The whole content of the file at `path` (empty when it cannot be read).
std::string slurp(const std::string& path);

/// `word` as one single-quoted word for /bin/sh.
std::string quote(const std::string& word);

/// Runs the built `drivenshape` binary with `args` through the shell. Its stdout and stderr go
/// to hidden files in `dir` (".stdout", ".stderr"), which are read back and removed.
CliRun runCli(const TempDir& dir, const std::vector<std::string>& args);

/// Path of `name` in the bundled sleeve sample (tests/data/sleeve).
std::string sample(const std::string& name);

}  // namespace drivenshape::testing
