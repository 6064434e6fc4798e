// SPDX-License-Identifier: Apache-2.0
// drivenshape: the command line. Picks the command, runs it, and turns every error into one
// line on stderr and a documented exit code (see drivenshape::ErrorCode and docs/commands.md).

#include <cstdio>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/version.h>

#include "commands.h"
#include "eval_command.h"
#include "export_command.h"
#include "farm_command.h"
#include "posmap_command.h"
#include "run_main.h"
#include "simulate_command.h"

namespace {

constexpr const char* kUsage =
    "usage: drivenshape COMMAND [options]   (drivenshape COMMAND --help for details)\n"
    "\n"
    "commands:\n"
    "  devices     list OpenCL platforms and devices\n"
    "  info FILE   describe a cache, mesh, database or EXR\n"
    "  db build    build a database from reference driver/driven caches\n"
    "  bake        bake a shot into point-cache EXRs\n"
    "  eval        compare a bake with a truth cache\n"
    "  posmap      write UV-space position maps (P, A, N) for compositing\n"
    "  farm        write Slurm array scripts or Open Job Description templates for a shot\n"
    "  export      write a result as PC2 and/or a first-frame OBJ (guides for simulation)\n"
    "  simulate    simulate the frames a bake's verdict flags in Blender and splice them in\n"
    "  version     print the version\n";

int dispatch(const std::vector<std::string>& words) {
  using namespace drivenshape::cli;
  if (words.empty() || words[0] == "-h" || words[0] == "--help" || words[0] == "help") {
    std::fputs(kUsage, words.empty() ? stderr : stdout);
    return words.empty() ? 2 : 0;
  }
  const std::string& command = words[0];
  const std::vector<std::string> rest(words.begin() + 1, words.end());
  if (command == "version" || command == "--version") {
    std::printf("drivenshape %s\n", drivenshape::kVersion);
    return 0;
  }
  if (command == "devices") {
    return runDevices(rest);
  }
  if (command == "info") {
    return runInfo(rest);
  }
  if (command == "bake") {
    return runBake(rest);
  }
  if (command == "eval") {
    return runEval(rest);
  }
  if (command == "posmap") {
    return runPosmap(rest);
  }
  if (command == "farm") {
    return runFarm(rest);
  }
  if (command == "export") {
    return runExport(rest);
  }
  if (command == "simulate") {
    return runSimulate(rest);
  }
  if (command == "db") {
    if (!rest.empty() && rest[0] == "build") {
      return runDbBuild(std::vector<std::string>(rest.begin() + 1, rest.end()));
    }
    DS_THROW(kUsage, "`drivenshape db` needs a subcommand: build");
  }
  DS_THROW(kUsage, "unknown command '", command, "'; run `drivenshape --help`");
}

}  // namespace

int main(int argc, char** argv) {
  return drivenshape::cli::runMain("drivenshape", argc, argv, dispatch);
}
