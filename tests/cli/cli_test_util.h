// SPDX-License-Identifier: Apache-2.0
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

/// Like runCli, but sends SIGTERM to the process `seconds` after it starts (as a farm
/// scheduler stopping a task does) and waits for it.
CliRun runCliStopped(const TempDir& dir, const std::vector<std::string>& args, double seconds);

/// Path of `name` in the bundled sleeve sample (tests/data/sleeve).
std::string sample(const std::string& name);

/// `db build` of the sample's train clip (rest meshes, driver and driven caches), then `extra`.
std::vector<std::string> sampleDbBuild(const std::vector<std::string>& extra = {});

/// Builds a small database of the sample (5 shapes) in `dir` with the CLI; returns its path.
std::string buildDb(const TempDir& dir);
/// The same with `db build`'s defaults otherwise (the pose model), as `name` in `dir`.
std::string buildPoseDb(const TempDir& dir, const std::string& name = "pose.dsdb");

/// Files in `dir` (recursively) other than the harness's own; leftover temporary files
/// (`.name.tmp-*`) are listed too, since one is a failure.
std::vector<std::string> filesIn(const std::string& dir);

/// A one-line error ("drivenshape: <kind>: ...") naming `fragment`, with exit code `code`.
void expectError(const CliRun& r, int code, const std::string& fragment);

}  // namespace drivenshape::testing
