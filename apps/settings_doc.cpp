// SPDX-License-Identifier: Apache-2.0
// drivenshape_settings_doc: writes the settings table (drivenshape/settings_table.h) into
// docs/commands.md between its marker lines (the evaluator's and bake's settings, the layer
// options, db build's settings, simulate's settings: one pair of lines each), or checks that the
// file holds it (CTest settings_doc: a stale table fails CI). --json prints the table for the
// scripts that generate the Blender add-on's settings and the report schema's (scripts/
// generate_from_settings.py).
//
//   drivenshape_settings_doc docs/commands.md --write        (after changing a setting)
//   drivenshape_settings_doc docs/commands.md --out TMP.md    (regenerate to TMP.md and compare)
//   drivenshape_settings_doc --json                           (the table, for scripts)

#include <fstream>
#include <iostream>
#include <sstream>

#include <drivenshape/error.h>
#include <drivenshape/settings_table.h>

#include "cli_args.h"
#include "run_main.h"

namespace ds = drivenshape;

namespace {

/// One generated table of the document: its marker lines and its text.
struct Table {
  const char* begin;
  const char* end;
  std::string (*text)();
};

std::string layerTable() {
  return ds::settingsTableMarkdown(ds::SettingScope::kLayer);
}

std::string buildTable() {
  return ds::settingsTableMarkdown(ds::SettingScope::kBuild);
}

std::string simulateTable() {
  return ds::settingsTableMarkdown(ds::SettingScope::kSimulate);
}

const Table kTables[] = {
    {"<!-- settings table: generated from src/pipeline/settings_table.cpp by "
     "drivenshape_settings_doc; do not edit by hand -->",
     "<!-- end of the settings table -->", [] { return ds::settingsTableMarkdown(); }},
    {"<!-- layer options: generated from src/pipeline/settings_table.cpp by "
     "drivenshape_settings_doc; do not edit by hand -->",
     "<!-- end of the layer options -->", &layerTable},
    {"<!-- db build settings: generated from src/pipeline/settings_table.cpp by "
     "drivenshape_settings_doc; do not edit by hand -->",
     "<!-- end of the db build settings -->", &buildTable},
    {"<!-- simulate settings: generated from src/pipeline/settings_table.cpp by "
     "drivenshape_settings_doc; do not edit by hand -->",
     "<!-- end of the simulate settings -->", &simulateTable}};

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    DS_THROW(kInput, "cannot read '", path, "'");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// `document` with the text between each table's marker lines replaced by the table.
std::string withTables(std::string document, const std::string& path) {
  for (const Table& table : kTables) {
    const std::size_t begin = document.find(table.begin);
    const std::size_t end = document.find(table.end);
    if (begin == std::string::npos || end == std::string::npos || end < begin) {
      DS_THROW(kInput, "'", path, "' lacks a settings table's marker lines:\n", table.begin, "\n",
               table.end);
    }
    const std::size_t after = begin + std::string(table.begin).size();
    document = document.substr(0, after) + "\n" + table.text() + document.substr(end);
  }
  return document;
}

/// The 1-based number of the first line where `a` and `b` differ.
int firstDifferentLine(const std::string& a, const std::string& b) {
  std::istringstream x(a), y(b);
  std::string lineA, lineB;
  for (int line = 1;; ++line) {
    const bool moreA = static_cast<bool>(std::getline(x, lineA));
    const bool moreB = static_cast<bool>(std::getline(y, lineB));
    if (moreA != moreB || lineA != lineB) {
      return line;
    }
    if (!moreA) {
      return 0;
    }
  }
}

int run(const std::vector<std::string>& args) {
  if (args == std::vector<std::string>{"--json"}) {
    std::cout << ds::settingsTableJson() << "\n";
    return 0;
  }
  ds::cli::ArgParser parser("drivenshape_settings_doc DOC.md [--write | --out PATH] | --json",
                            "Puts the settings tables into DOC.md between their marker lines "
                            "(--write), or writes the regenerated document to PATH and fails "
                            "when it differs from DOC.md. --json alone prints the table as "
                            "JSON.");
  parser.positional("DOC.md", 1)
      .flag("--write", "rewrite DOC.md in place")
      .option("--out", "PATH", "where the regenerated document goes when checking");
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const std::string path = parser.positionals().front();
  const std::string current = readText(path);
  const std::string regenerated = withTables(current, path);
  const std::string out = parser.has("--write") ? path : parser.get("--out");
  if (!out.empty()) {
    std::ofstream(out, std::ios::binary) << regenerated;
  }
  if (parser.has("--write") || regenerated == current) {
    return 0;
  }
  std::cerr << path << ": the settings table is stale (first difference at line "
            << firstDifferentLine(current, regenerated)
            << "; regenerated: " << (out.empty() ? std::string("not written") : out)
            << ").\nRegenerate it: build/apps/drivenshape_settings_doc " << path << " --write\n";
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  return drivenshape::cli::runMain("drivenshape_settings_doc", argc, argv, run);
}
