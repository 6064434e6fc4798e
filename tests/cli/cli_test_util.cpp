// SPDX-License-Identifier: Apache-2.0
#include "cli_test_util.h"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace drivenshape::testing {

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string quote(const std::string& word) {
  std::string quoted = "'";
  for (char ch : word) {
    quoted += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
  }
  return quoted + "'";
}

namespace {

/// Runs `command` (the CLI with its arguments) through the shell; with `stopAfter` > 0 the
/// shell sends it SIGTERM after that many seconds and exits with its status.
CliRun runShell(const TempDir& dir, const std::vector<std::string>& args, double stopAfter) {
  std::string command = quote(DS_CLI_PATH);
  for (const auto& arg : args) {
    command += " " + quote(arg);
  }
  const std::string out = dir.file(".stdout"), err = dir.file(".stderr");
  command += " >" + quote(out) + " 2>" + quote(err);
  if (stopAfter > 0) {
    command = command + " & pid=$!; sleep " + std::to_string(stopAfter) +
              "; kill -TERM $pid 2>/dev/null; wait $pid";
  }
  const int status = std::system(command.c_str());
  CliRun result;
  result.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = slurp(out);
  result.err = slurp(err);
  std::filesystem::remove(out);
  std::filesystem::remove(err);
  return result;
}

}  // namespace

CliRun runCli(const TempDir& dir, const std::vector<std::string>& args) {
  return runShell(dir, args, 0.0);
}

CliRun runCliStopped(const TempDir& dir, const std::vector<std::string>& args, double seconds) {
  return runShell(dir, args, seconds);
}

std::string sample(const std::string& name) {
  return dataDir() + "/sleeve/" + name;
}

std::vector<std::string> sampleDbBuild(const std::vector<std::string>& extra) {
  std::vector<std::string> args{"db",
                                "build",
                                "--driver-mesh",
                                sample("driver_rest.obj"),
                                "--driven-mesh",
                                sample("driven_rest.obj"),
                                "--driver",
                                sample("train.driver.pc2"),
                                "--driven",
                                sample("train.driven.pc2")};
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

std::string buildDb(const TempDir& dir) {
  const std::string db = dir.file("sleeve.dsdb");
  const CliRun r =
      runCli(dir, sampleDbBuild({"--count", "5", "--model", "none", "--quiet", "-o", db}));
  EXPECT_EQ(r.code, 0) << r.err;
  return db;
}

std::string buildPoseDb(const TempDir& dir, const std::string& name) {
  const std::string db = dir.file(name);
  const CliRun r = runCli(dir, sampleDbBuild({"--count", "5", "--quiet", "-o", db}));
  EXPECT_EQ(r.code, 0) << r.err;
  return db;
}

std::vector<std::string> filesIn(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (entry.is_regular_file() && (name[0] != '.' || name.find(".tmp-") != std::string::npos)) {
      names.push_back(entry.path().string());
    }
  }
  return names;
}

void expectError(const CliRun& r, int code, const std::string& fragment) {
  EXPECT_EQ(r.code, code) << r.err;
  std::istringstream lines(r.err);
  std::vector<std::string> errors;
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("drivenshape: ", 0) == 0) {
      errors.push_back(line);
    }
  }
  ASSERT_EQ(errors.size(), 1u) << "stderr: " << r.err;
  EXPECT_NE(errors[0].find(fragment), std::string::npos) << "stderr: " << r.err;
}

}  // namespace drivenshape::testing
