// Regressions found by trying the command line as a hostile user would (and by fuzzing): each
// test re-creates one reported input and pins the documented exit code and a message that
// names the file, frame or flag at fault. None of these may crash or exit 1 (internal error).

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include <drivenshape/point_cache.h>

#include "cli_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

namespace fs = std::filesystem;
using testing::buildDb;
using testing::CliRun;
using testing::expectError;
using testing::filesIn;
using testing::runCli;
using testing::sample;
using testing::slurp;
using testing::TempDir;

std::vector<std::string> bakeArgs(const std::string& db, const std::string& frames,
                                  const std::string& output) {
  return {"bake",     "--db", db,        "--driver", sample("test.driver.pc2"),
          "--frames", frames, "--quiet", "-o",       output};
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

/// The sample's driven OBJ with its first face's first corner replaced by `corner`.
std::string objWithCorner(const TempDir& dir, const std::string& corner) {
  std::string text = slurp(sample("driven_rest.obj"));
  const std::size_t face = text.find("\nf ");
  const std::size_t end = text.find(' ', face + 3);
  text.replace(face + 3, end - face - 3, corner);
  const std::string path = dir.file("crafted.obj");
  writeText(path, text);
  return path;
}

// An OBJ face index of -2147483648 overflowed on negation; `info` and `db build` then
// accepted the file, and `posmap --mesh` overflowed the heap.
TEST(CliRegression, ObjIndexIntMinIsAnInputErrorInEveryCommand) {
  TempDir dir;
  const std::string obj = objWithCorner(dir, "-2147483648/1");
  expectError(runCli(dir, {"info", obj}), 3, "crafted.obj:");
  expectError(
      runCli(dir, {"db", "build", "--driver-mesh", sample("driver_rest.obj"), "--driven-mesh", obj,
                   "--driver", sample("train.driver.pc2"), "--driven", sample("train.driven.pc2"),
                   "--count", "3", "--quiet", "-o", dir.file("x.dsdb")}),
      3, "crafted.obj:");
  expectError(runCli(dir, {"posmap", "--mesh", obj, "--cache", sample("test.driven.pc2"),
                           "--frames", "1", "--res", "64", "-o", dir.file("p.####.exr")}),
              3, "crafted.obj:");
  EXPECT_TRUE(filesIn(dir.path()).size() == 1u) << "only crafted.obj may exist";
}

// Group names and output paths that are not UTF-8 made every JSON writer throw: `bake`
// wrote all frames, then exited 1 without a report, and every farm retry failed the same way.
TEST(CliRegression, NamesAndPathsThatAreNotUtf8BakeWithAReport) {
  TempDir dir;
  std::string text = slurp(sample("driven_rest.obj"));
  const std::size_t object = text.find("\no ");
  ASSERT_NE(object, std::string::npos);
  text.insert(object + 3, "caf\xe9\xff ");
  writeText(dir.file("latin1.obj"), text);
  const std::string db = dir.file("latin1.dsdb");
  CliRun r =
      runCli(dir, {"db", "build", "--driver-mesh", sample("driver_rest.obj"), "--driven-mesh",
                   dir.file("latin1.obj"), "--driver", sample("train.driver.pc2"), "--driven",
                   sample("train.driven.pc2"), "--count", "3", "--quiet", "-o", db});
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string folder = dir.file("sh\xf6t");
  fs::create_directory(folder);
  r = runCli(dir, bakeArgs(db, "1-2", folder + "/cloth.####.exr"));
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(folder + "/cloth.report.json"));
  EXPECT_EQ(report.at("frames").size(), 2u);
  r = runCli(dir, {"info", db});
  EXPECT_EQ(r.code, 0) << r.err;
}

// A bind mask holding 1e999 escaped as a JSON out_of_range error (exit 1).
TEST(CliRegression, BindMaskNumberBeyondDoubleIsAnInputError) {
  TempDir dir;
  const std::string db = buildDb(dir);
  writeText(dir.file("mask.json"),
            R"({"bindings": [{"driven": {"vertices": [1e999]}, "driver": {"faces": [0]}}]})");
  expectError(runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames",
                           "1", "--bind", dir.file("mask.json"), "-o", dir.file("o.####.exr")}),
              3, "mask.json");
}

// A folder given where a file is read was basic_filebuf::underflow (exit 1).
TEST(CliRegression, FolderGivenAsAnInputFileIsAnInputError) {
  TempDir dir;
  const std::string db = buildDb(dir);
  fs::create_directory(dir.file("folder.dsdb"));
  expectError(runCli(dir, bakeArgs(dir.file("folder.dsdb"), "1", dir.file("o.####.exr"))), 3,
              "folder.dsdb");
  fs::create_directory(dir.file("weights.json"));
  std::vector<std::string> args = bakeArgs(db, "1", dir.file("o.####.exr"));
  args.insert(args.end(),
              {"--mix", sample("test.driven.pc2"), "--mix-weight", dir.file("weights.json")});
  expectError(runCli(dir, args), 3, "weights.json");
  expectError(runCli(dir, {"info", dir.file("folder.dsdb")}), 3, "folder.dsdb");
}

// `farm slurm --time` with a day count beyond a long was std::stol's out_of_range (exit 1).
TEST(CliRegression, FarmTimeLimitOutOfRangeIsAUsageError) {
  TempDir dir;
  const std::string db = buildDb(dir);
  CliRun r = runCli(dir, {"farm", "slurm", "--time", "99999999999999999999-00:00:00", "--db", db,
                          "--driver", sample("test.driver.pc2"), "--frames", "1-4", "-o",
                          dir.file("o.####.exr"), "--chunk-size", "2", "-O", dir.file("job.sh")});
  expectError(r, 2, "--time");
  r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1",
                   "--device", "99999999999999999999999", "-o", dir.file("o.####.exr")});
  EXPECT_NE(r.code, 1) << r.err;
  EXPECT_NE(r.code, 0) << r.err;
}

// SIGTERM before the bake loop (loading, device setup) exited 143 instead of 7; whenever it
// comes, the run stops with 7, and finished frames are whole and no temporary file is left.
TEST(CliRegression, SigtermDuringSetupOrBakeExitsSeven) {
  TempDir dir;
  const std::string db = buildDb(dir);
  for (double after : {0.25, 0.8}) {
    SCOPED_TRACE(after);
    const std::string out = dir.file("stop" + std::to_string(int(after * 100)));
    fs::create_directory(out);
    const CliRun r =
        testing::runCliStopped(dir, bakeArgs(db, "1-48", out + "/cloth.####.exr"), after);
    if (r.code == 0) {
      continue;  // finished before the signal: nothing to check
    }
    EXPECT_EQ(r.code, 7) << r.err;
    for (const std::string& file : filesIn(out)) {
      EXPECT_EQ(file.find(".tmp-"), std::string::npos) << file;
      if (file.size() > 4 && file.substr(file.size() - 4) == ".exr") {
        EXPECT_TRUE(isCompleteExr(file)) << file;
      }
    }
  }
}

// --temporal-warmup 1000000000 on a 3-frame bake walked a billion frame numbers (35 s).
TEST(CliRegression, HugeTemporalWarmupCostsNothing) {
  TempDir dir;
  const std::string db = buildDb(dir);
  std::vector<std::string> args = bakeArgs(db, "1-3", dir.file("o.####.exr"));
  args.insert(args.end(), {"--max-weight-change", "0.1", "--temporal-warmup", "1000000000"});
  const auto start = std::chrono::steady_clock::now();
  const CliRun r = runCli(dir, args);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(r.code, 0) << r.err;
  // Not a speed target: a hang detector. The bake itself takes about a second.
  EXPECT_LT(seconds, 30.0);
}

/// Frames 1-3 of the sample baked into `out`, uncompressed so that a flipped byte still
/// decodes.
std::vector<std::string> bakeThree(const TempDir& dir, const std::string& db,
                                   const std::string& out, std::vector<std::string> extra = {}) {
  std::vector<std::string> args = bakeArgs(db, "1-3", out + "/cloth.####.exr");
  args.insert(args.end(), {"--compression", "none", "--skip-existing"});
  args.insert(args.end(), extra.begin(), extra.end());
  const CliRun r = runCli(dir, args);
  EXPECT_EQ(r.code, 0) << r.err;
  return {out + "/cloth.0001.exr", out + "/cloth.0002.exr", out + "/cloth.0003.exr", r.err};
}

// A resume kept frames whose pixels were damaged after writing (34 of 62 mutated frames were
// kept, 21 of them undecodable). Now a frame is kept only if it decodes to the CRC written
// with it; a damaged frame is baked again, named in the log, and comes out bitwise as before.
TEST(CliRegression, ResumeRebakesAFrameWithOneFlippedPixelByte) {
  TempDir dir;
  const std::string db = buildDb(dir);
  const std::string out = dir.file("shot");
  fs::create_directory(out);
  const std::vector<std::string> first = bakeThree(dir, db, out);
  const std::string original = slurp(first[1]);
  ASSERT_GT(original.size(), 20000u);
  for (std::size_t at : {original.size() / 2, original.size() * 3 / 4, original.size() - 5}) {
    std::string damaged = original;
    damaged[at] = static_cast<char>(damaged[at] ^ 0x10);
    writeText(first[1], damaged);
    const auto keptBefore = fs::last_write_time(first[0]);
    const std::vector<std::string> again = bakeThree(dir, db, out);
    EXPECT_NE(again[3].find("rebaked frame 2"), std::string::npos) << again[3];
    EXPECT_EQ(again[3].find("rebaked frame 1"), std::string::npos) << again[3];
    EXPECT_EQ(slurp(first[1]), original) << "byte " << at;
    EXPECT_EQ(fs::last_write_time(first[0]), keptBefore) << "frame 1 was rewritten";
  }
}

// A temporary file left by SIGKILL was never removed by a resume.
TEST(CliRegression, ResumeRemovesTemporaryFilesOfItsOwnFrames) {
  TempDir dir;
  const std::string db = buildDb(dir);
  const std::string out = dir.file("shot");
  fs::create_directory(out);
  writeText(out + "/.cloth.0002.exr.tmp-99999-0", "half a frame");
  writeText(out + "/.cloth.0009.exr.tmp-99999-0", "another task's frame");
  const std::vector<std::string> baked = bakeThree(dir, db, out);
  EXPECT_FALSE(fs::exists(out + "/.cloth.0002.exr.tmp-99999-0"));
  EXPECT_TRUE(fs::exists(out + "/.cloth.0009.exr.tmp-99999-0"));
  EXPECT_NE(baked[3].find("removed 1 temporary file"), std::string::npos) << baked[3];
}

}  // namespace
}  // namespace drivenshape
