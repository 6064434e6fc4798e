// SPDX-License-Identifier: Apache-2.0
// A stand-in for Blender in test_simulate_command: it checks the command line `drivenshape
// simulate` gives Blender and its runner (docs/commands.md, "drivenshape simulate") and writes
// what a runner writes, one point-cache EXR per frame --first..--last, so that the command's
// plumbing (windows, reuse, failures, splice, report) is tested without Blender. It simulates
// nothing: the real runner is tested in Blender by tests/blender.
//
//   stand_in_blender -b SHOT.blend --python-exit-code 1 --python RUNNER -- --object GARMENT
//       --bake BAKE.####.exr --first A --last B --goal-strength S -o OUT.####.exr
//
// Frame f of the output is the bake's frame f moved by simulatedOffset(f, vertex, axis).
// $STAND_IN_LOG, when set, gets the words after `--` of every run, one run per line;
// $STAND_IN_FAIL_AT=F makes a run whose frames hold F write the frames before F and exit 1;
// $STAND_IN_HANG=PATH makes a run write its process id to PATH and wait (up to a minute) for a
// signal, as a long simulation would.

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <unistd.h>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/point_cache.h>

#include "stand_in_blender.h"

namespace {

int fail(const std::string& message) {
  std::fprintf(stderr, "stand-in blender: %s\n", message.c_str());
  return 1;
}

/// The words before `--` as Blender takes them, checked; the runner's options after it.
bool parse(int argc, char** argv, std::map<std::string, std::string>& options, std::string& log) {
  const std::vector<std::string> blender = {"-b", "",  "--python-exit-code", "1", "--python",
                                            "",   "--"};
  if (argc != 1 + static_cast<int>(blender.size()) + 12) {
    return false;
  }
  for (std::size_t i = 0; i < blender.size(); ++i) {
    if (!blender[i].empty() && blender[i] != argv[1 + i]) {
      return false;
    }
  }
  options["blend"] = argv[2];
  options["runner"] = argv[6];
  for (int i = 1 + static_cast<int>(blender.size()); i + 1 < argc; i += 2) {
    options[argv[i]] = argv[i + 1];
    log += std::string(argv[i]) + " " + argv[i + 1] + " ";
  }
  for (const char* key : {"--object", "--bake", "--first", "--last", "--goal-strength", "-o"}) {
    if (options.count(key) == 0) {
      return false;
    }
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> options;
  std::string words;
  if (!parse(argc, argv, options, words)) {
    return fail("not the command line of drivenshape simulate's runner");
  }
  if (!std::ifstream(options["blend"]) || !std::ifstream(options["runner"])) {
    return fail("the scene or the runner does not exist");
  }
  if (const char* log = std::getenv("STAND_IN_LOG")) {
    std::ofstream(log, std::ios::app) << words << "\n";
  }
  if (const char* hang = std::getenv("STAND_IN_HANG")) {
    std::ofstream(hang) << ::getpid() << "\n";
    for (int i = 0; i < 600; ++i) {
      ::usleep(100000);
    }
    return fail("no signal came within a minute");
  }
  const int first = std::atoi(options["--first"].c_str());
  const int last = std::atoi(options["--last"].c_str());
  const char* failAt = std::getenv("STAND_IN_FAIL_AT");
  try {
    std::vector<float> xyz;
    for (int f = first; f <= last; ++f) {
      if (failAt != nullptr && std::atoi(failAt) == f) {
        return fail("the cloth exploded at frame " + std::to_string(f));
      }
      const std::string bake = drivenshape::expandFramePattern(options["--bake"], f);
      const drivenshape::ExrPointCacheInfo info = drivenshape::readPointCacheExr(bake, xyz);
      for (std::size_t i = 0; i < xyz.size(); ++i) {
        xyz[i] += drivenshape::testing::simulatedOffset(f, static_cast<int>(i / 3),
                                                        static_cast<int>(i % 3));
      }
      drivenshape::ExrWriteOptions write;
      write.frame = f;
      write.topologyHash = info.topologyHash;
      drivenshape::writePointCacheExr(drivenshape::expandFramePattern(options["-o"], f),
                                      info.vertexCount, xyz.data(), nullptr, write);
    }
  } catch (const drivenshape::Error& error) {
    return fail(error.what());
  }
  return 0;
}
