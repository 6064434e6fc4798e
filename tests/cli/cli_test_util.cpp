#include "cli_test_util.h"

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

CliRun runCli(const TempDir& dir, const std::vector<std::string>& args) {
  std::string command = quote(DS_CLI_PATH);
  for (const auto& arg : args) {
    command += " " + quote(arg);
  }
  const std::string out = dir.file(".stdout"), err = dir.file(".stderr");
  command += " >" + quote(out) + " 2>" + quote(err);
  const int status = std::system(command.c_str());
  CliRun result;
  result.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = slurp(out);
  result.err = slurp(err);
  std::filesystem::remove(out);
  std::filesystem::remove(err);
  return result;
}

std::string sample(const std::string& name) {
  return dataDir() + "/sleeve/" + name;
}

}  // namespace drivenshape::testing
