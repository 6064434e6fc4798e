// SPDX-License-Identifier: Apache-2.0
// Issue 42 ("nothing lost, part two"): every command runs as a real process against inputs an
// attacker or a hurried TD would give it, and must refuse before it writes where it must not,
// stop cleanly, and name the file and the bound at fault with the documented exit code.

#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <sys/stat.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <drivenshape/database.h>
#include <drivenshape/frames.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

#include "atomic_file.h"
#include "cli_test_util.h"
#include "hash.h"
#include "test_support.h"

namespace drivenshape {
namespace {

namespace fs = std::filesystem;
using testing::buildDb;
using testing::CliRun;
using testing::expectError;
using testing::runCli;
using testing::sample;
using testing::sampleDbBuild;
using testing::slurp;
using testing::TempDir;

void writeText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

/// The sample's test driver as an EXR sequence `pattern` (frames 1-8).
void writeDriverSequence(const std::string& pattern) {
  const auto cache = openPc2(sample("test.driver.pc2"));
  std::vector<float> xyz(static_cast<std::size_t>(cache->vertexCount()) * 3);
  for (int frame = 1; frame <= 8; ++frame) {
    cache->readFrame(frame, xyz.data());
    ExrWriteOptions options;
    options.frame = frame;
    options.syncToDisk = false;
    writePointCacheExr(expandFramePattern(pattern, frame), cache->vertexCount(), xyz.data(),
                       nullptr, options);
  }
}

/// A --mix-weight / --wind-weight map of the sample's driven mesh (0.5 everywhere).
std::string writeWeightMap(const std::string& path) {
  const int vertices = readObj(sample("driven_rest.obj")).vertexCount();
  std::string text = "[";
  for (int v = 0; v < vertices; ++v) {
    text += v == 0 ? "0.5" : ",0.5";
  }
  writeText(path, text + "]");
  return path;
}

/// `args` with `extra` appended.
std::vector<std::string> with(std::vector<std::string> args,
                              const std::vector<std::string>& extra) {
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

/// Runs `args`, expects a usage error naming `option`, and `victim` still holding `content`.
void expectRefused(const TempDir& dir, const std::vector<std::string>& args,
                   const std::string& option, const std::string& victim,
                   const std::string& content) {
  const CliRun r = runCli(dir, args);
  expectError(r, 2, option);
  EXPECT_EQ(slurp(victim), content) << victim << " was overwritten";
}

// ---- Defects 3-6: outputs compared with every input by file identity ----

// `bake --report` overwrote driver frames outside --frames (the pose model reads them as
// history), --mix, --mix-weight and --wind-weight; and any output naming the target of an
// input that is a link (or the link of an input) replaced the input.
TEST(CliSafety, BakeOutputsNeverReplaceAnyInputByNameOrIdentity) {
  TempDir dir;
  const std::string db = buildDb(dir);
  const std::string drivers = dir.file("drv.####.exr");
  writeDriverSequence(drivers);
  const std::string history = dir.file("drv.0002.exr");
  const std::string historyBytes = slurp(history);
  const std::vector<std::string> bake = {
      "bake",     "--db", db,        "--driver", drivers,
      "--frames", "5-6",  "--quiet", "-o",       dir.file("o.####.exr")};
  expectRefused(dir, with(bake, {"--report", history}), "--driver", history, historyBytes);

  // --mix (a PC2) reached through a link; the output names the link's target, and the reverse.
  const std::string mix = dir.file("mix.pc2");
  fs::copy_file(sample("test.driven.pc2"), mix);
  const std::string mixBytes = slurp(mix);
  fs::create_symlink(mix, dir.file("mix-link.pc2"));
  expectRefused(dir, with(bake, {"--mix", dir.file("mix-link.pc2"), "--report", mix}), "--mix", mix,
                mixBytes);
  expectRefused(dir, with(bake, {"--mix", mix, "--report", dir.file("mix-link.pc2")}), "--mix", mix,
                mixBytes);
  // A hard link of --mix at a frame's name.
  fs::create_hard_link(mix, dir.file("o.0006.exr"));
  expectRefused(dir, with(bake, {"--mix", mix}), "--mix", mix, mixBytes);
  fs::remove(dir.file("o.0006.exr"));

  // --mix as an earlier bake's EXR sequence (any of its frames), through a linked folder.
  fs::create_directory(dir.file("prev"));
  writeDriverSequence(dir.file("prev/c.####.exr"));
  const std::string earlier = dir.file("prev/c.0001.exr");
  const std::string earlierBytes = slurp(earlier);
  fs::create_symlink(dir.file("prev"), dir.file("linked"));
  expectRefused(dir, with(bake, {"--mix", dir.file("linked/c.####.exr"), "--report", earlier}),
                "--mix", earlier, earlierBytes);

  for (const char* option : {"--mix-weight", "--wind-weight"}) {
    SCOPED_TRACE(option);
    const std::string map = writeWeightMap(dir.file("weights.json"));
    const std::string mapBytes = slurp(map);
    fs::create_symlink(map, dir.file("weights-link.json"));
    std::vector<std::string> layer = {
        "--mix", sample("test.driven.pc2"), option, dir.file("weights-link.json"), "--report", map};
    if (std::string(option) == "--wind-weight") {
      layer = {"--wind-amplitude", "0.01", option, dir.file("weights-link.json"), "--report", map};
    }
    expectRefused(dir, with(bake, layer), option, map, mapBytes);
    fs::remove(dir.file("weights-link.json"));
  }
  // The database through a link, named by --report.
  const std::string dbBytes = slurp(db);
  fs::create_symlink(db, dir.file("db-link.dsdb"));
  expectRefused(dir,
                {"bake", "--db", dir.file("db-link.dsdb"), "--driver", drivers, "--frames", "5",
                 "--quiet", "-o", dir.file("o.####.exr"), "--report", db},
                "--db", db, dbBytes);
  EXPECT_FALSE(fs::exists(dir.file("o.0005.exr")));
}

// `db build -o`, `--suggest-json` and `--model-json` overwrote --also, --candidate and --shot
// caches (simulated reference clips); through a link too.
TEST(CliSafety, DbBuildOutputsNeverReplaceAClip) {
  TempDir dir;
  const std::string also = dir.file("also.driven.pc2");
  fs::copy_file(sample("test.driven.pc2"), also);
  const std::string alsoBytes = slurp(also);
  fs::create_symlink(also, dir.file("also-link.pc2"));
  const std::vector<std::string> build = sampleDbBuild({"--count", "3", "--quiet"});
  expectRefused(
      dir,
      with(build, {"--also", sample("test.driver.pc2"), dir.file("also-link.pc2"), "-o", also}),
      "--also", also, alsoBytes);
  expectRefused(dir,
                with(build, {"--also", sample("test.driver.pc2"), also + ":1-10", "-o",
                             dir.file("x.dsdb"), "--model-json", dir.file("also-link.pc2")}),
                "--also", also, alsoBytes);
  const std::string shot = dir.file("shot.driver.pc2");
  fs::copy_file(sample("test.driver.pc2"), shot);
  const std::string shotBytes = slurp(shot);
  const std::vector<std::string> suggest = with(
      build, {"--suggest", "2", "--candidate", sample("test.driver.pc2"), "--shot", shot + ":1-5"});
  expectRefused(dir, with(suggest, {"--suggest-json", shot}), "--shot", shot, shotBytes);
  fs::create_hard_link(shot, dir.file("candidate.pc2"));
  expectRefused(dir,
                with(build, {"--suggest", "2", "--candidate", dir.file("candidate.pc2"), "--shot",
                             sample("test.driver.pc2"), "--suggest-json", shot}),
                "--candidate", shot, shotBytes);
  EXPECT_FALSE(fs::exists(dir.file("x.dsdb")));
}

// `farm slurm|openjd -O` overwrote --db or --driver; the OpenJD parameters file too.
TEST(CliSafety, FarmJobFilesNeverReplaceTheJobsInputs) {
  TempDir dir;
  const std::string db = buildDb(dir);
  const std::string dbBytes = slurp(db);
  const std::string driver = dir.file("shot.pc2");
  fs::copy_file(sample("test.driver.pc2"), driver);
  const std::string driverBytes = slurp(driver);
  fs::create_symlink(driver, dir.file("shot-link.pc2"));
  const std::vector<std::string> job = {"--frames",     "1-4", "-o", dir.file("out/c.####.exr"),
                                        "--chunk-size", "2"};
  expectRefused(dir, with({"farm", "slurm", "--db", db, "--driver", driver, "-O", db}, job), "--db",
                db, dbBytes);
  expectRefused(
      dir,
      with({"farm", "slurm", "--db", db, "--driver", dir.file("shot-link.pc2"), "-O", driver}, job),
      "--driver", driver, driverBytes);
  // `-O x.json` writes x.params.json beside it: a driver named so is an input as well.
  fs::create_symlink(driver, dir.file("job.params.json"));
  expectRefused(
      dir,
      with({"farm", "openjd", "--db", db, "--driver", driver, "-O", dir.file("job.json")}, job),
      "--driver", driver, driverBytes);
  EXPECT_FALSE(fs::exists(dir.file("job.json")));
}

// export, eval and posmap (whose --preview names were not checked at all) against inputs
// reached through links.
TEST(CliSafety, ExportEvalAndPosmapOutputsNeverReplaceALinkedInput) {
  TempDir dir;
  const std::string truth = dir.file("truth.pc2");
  fs::copy_file(sample("test.driven.pc2"), truth);
  const std::string truthBytes = slurp(truth);
  fs::create_symlink(truth, dir.file("truth-link.pc2"));
  expectRefused(
      dir, {"export", "--cache", dir.file("truth-link.pc2"), "--frames", "1-2", "--pc2", truth},
      "--cache", truth, truthBytes);
  expectRefused(dir,
                {"eval", "--truth", dir.file("truth-link.pc2"), "--bake", sample("test.driven.pc2"),
                 "--frames", "1-2", "--json", truth},
                "--truth", truth, truthBytes);
  const std::string mesh = dir.file("mesh.obj");
  fs::copy_file(sample("driven_rest.obj"), mesh);
  const std::string meshBytes = slurp(mesh);
  fs::create_symlink(mesh, dir.file("map.0001.png"));
  expectRefused(dir,
                {"posmap", "--mesh", mesh, "--cache", sample("test.driven.pc2"), "--frames", "1",
                 "--res", "32", "--preview", "-o", dir.file("map.####.exr")},
                "--preview", mesh, meshBytes);
  EXPECT_FALSE(fs::exists(dir.file("map.0001.exr")));
  expectError(
      runCli(dir, {"posmap", "--mesh", mesh, "--cache", sample("test.driven.pc2"), "--frames", "1",
                   "--res", "32", "--preview", "-o", dir.file("map.exr.####")}),
      2, "--preview");
}

// ---- Defect 13 and the stop: SIGXFSZ, SIGINT, SIGTERM ----

/// The CLI started as a child process (stdout and stderr to files in `dir`), optionally under
/// resource limits (`ulimit -f`, `ulimit -v`), for tests that limit or signal it.
class Child {
 public:
  Child(const TempDir& dir, const std::vector<std::string>& args,
        const std::vector<std::pair<int, rlim_t>>& limits = {})
      : mErr(dir.file(".child.stderr")) {
    const std::string out = dir.file(".child.stdout");
    mPid = ::fork();
    if (mPid == 0) {
      for (const auto& [resource, value] : limits) {
        const rlimit limit{value, value};
        ::setrlimit(resource, &limit);
      }
      const int outFd = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int errFd = ::open(mErr.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(outFd, 1);
      ::dup2(errFd, 2);
      std::vector<char*> argv{const_cast<char*>(DS_CLI_PATH)};
      for (const std::string& arg : args) {
        argv.push_back(const_cast<char*>(arg.c_str()));
      }
      argv.push_back(nullptr);
      ::execv(DS_CLI_PATH, argv.data());
      ::_exit(127);
    }
  }
  pid_t pid() const { return mPid; }
  /// Waits for the exit; the exit code, or 128 + the signal that ended it. `peakKib`, when
  /// given, receives the child's peak resident memory (KiB).
  int wait(long* peakKib = nullptr) {
    int status = 0;
    rusage usage{};
    ::wait4(mPid, &status, 0, &usage);
    if (peakKib != nullptr) {
      *peakKib = usage.ru_maxrss;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  std::string err() const { return slurp(mErr); }

 private:
  std::string mErr;
  pid_t mPid = -1;
};

/// Whether `folder` holds a temporary file of an atomic write.
bool holdsTempFile(const std::string& folder) {
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().filename().string().find(".tmp-") != std::string::npos) {
      return true;
    }
  }
  return false;
}

/// Every file left in `folder` (recursively), for messages.
std::string listing(const std::string& folder) {
  std::string text;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) {
    text += entry.path().filename().string() + " ";
  }
  return text;
}

// Under `ulimit -f` the bake died of SIGXFSZ (exit 153) and left its temporary file. The
// signal is ignored: the write fails with EFBIG, the temporary file is removed, exit 4.
TEST(CliSafety, FileSizeLimitEndsTheBakeWithAnOutputErrorAndNoTemporaryFile) {
  TempDir dir;
  const std::string db = buildDb(dir);
  const std::string out = dir.file("shot");
  fs::create_directory(out);
  // The host path: PoCL's kernel cache files would meet the limit first.
  Child child(dir,
              {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1-3",
               "--compression", "none", "--device", "host", "--quiet", "-o", out + "/c.####.exr"},
              {{RLIMIT_FSIZE, 16384}});
  const int code = child.wait();
  EXPECT_EQ(code, 4) << child.err();
  EXPECT_NE(child.err().find("output"), std::string::npos) << child.err();
  EXPECT_FALSE(holdsTempFile(out)) << listing(out);
}

// `farm openjd` wrote the job parameters file and then the template, each renamed into place on
// its own: when the template's write failed (a full disk), the new parameters file stayed beside
// the old template, a pair that does not match. Under a file-size limit that the parameters
// file fits and the template does not, the old pair must stay byte for byte, with no temporary
// file left beside it.
TEST(CliSafety, FarmOpenjdChangesTheTemplateAndItsParametersTogetherOrNotAtAll) {
  TempDir dir;
  const std::string job = dir.file("job.json");
  const std::string params = dir.file("job.params.json");
  const auto args = [&](const std::string& db) {
    return std::vector<std::string>{"farm",
                                    "openjd",
                                    "--db",
                                    db,
                                    "--driver",
                                    dir.file("d.pc2"),
                                    "--frames",
                                    "1-48",
                                    "-o",
                                    dir.file("out/c.####.exr"),
                                    "--chunk-size",
                                    "16",
                                    "--no-check",
                                    "-O",
                                    job};
  };
  ASSERT_EQ(runCli(dir, args(dir.file("old.dsdb"))).code, 0);
  const std::string oldJob = slurp(job);
  const std::string oldParams = slurp(params);
  ASSERT_LT(oldParams.size() + 64, 1024u);  // the limit below: the parameters file fits,
  ASSERT_GT(oldJob.size(), 1024u);          // the template does not
  Child child(dir, args(dir.file("new.dsdb")), {{RLIMIT_FSIZE, 1024}});
  const int code = child.wait();
  EXPECT_EQ(code, 4) << child.err();
  EXPECT_NE(child.err().find("job.json"), std::string::npos) << child.err();
  EXPECT_EQ(slurp(params), oldParams) << "the parameters file changed without its template";
  EXPECT_EQ(slurp(job), oldJob);
  EXPECT_FALSE(holdsTempFile(dir.path())) << listing(dir.path());
  // Without the limit both change.
  ASSERT_EQ(runCli(dir, args(dir.file("new.dsdb"))).code, 0);
  EXPECT_NE(slurp(params).find("new.dsdb"), std::string::npos);
  EXPECT_NE(slurp(job), oldJob);
}

// `posmap --res 16384` (the documented maximum) needed about 17 GB for one frame of the sample:
// the whole map's tables (20 bytes per texel, twice: the backend copied them), its positions and
// its compressed file were all held at once. A map whose tables pass 1 GiB is now rasterised,
// evaluated and written a band of rows at a time. 8192 x 3072 texels of the sample (about 1.6 GB
// before) must stay within 512 MiB.
TEST(CliSafety, LargePositionMapsAreWrittenWithinAFewHundredMegabytes) {
  TempDir dir;
  Child child(dir, {"posmap", "--mesh", sample("driven_rest.obj"), "--cache",
                    sample("test.driven.pc2"), "--frames", "1", "--res", "8192x3072", "--device",
                    "host", "--quiet", "-o", dir.file("m.####.exr")});
  long peakKib = 0;
  ASSERT_EQ(child.wait(&peakKib), 0) << child.err();
  EXPECT_LT(peakKib, 512L * 1024) << "peak resident memory " << peakKib / 1024 << " MiB";
  EXPECT_GT(fs::file_size(dir.file("m.0001.exr")), 100u << 20);
  EXPECT_FALSE(holdsTempFile(dir.path())) << listing(dir.path());
}

// Ctrl-C or SIGTERM while the only batch of a shot is being written was ignored: the run went
// on, wrote the report and exited 0. The child is frozen while one of its temporary files
// exists (so the signal lands mid-batch, deterministically), signalled, and let go: it must
// exit 7 with whole frames, no temporary file and no report.
TEST(CliSafety, StopDuringTheOnlyBatchExitsSevenWithoutAReport) {
  TempDir dir;
  const std::string db = buildDb(dir);
  for (int signal : {SIGINT, SIGTERM}) {
    SCOPED_TRACE(signal);
    bool caught = false;
    for (int attempt = 0; attempt < 5 && !caught; ++attempt) {
      const std::string out =
          dir.file("stop" + std::to_string(signal) + "_" + std::to_string(attempt));
      fs::create_directory(out);
      Child child(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames",
                        "1-48", "--batch", "48", "--sync", "--compression", "zip", "--quiet", "-o",
                        out + "/c.####.exr"});
      int status = 0;
      while (::waitpid(child.pid(), &status, WNOHANG) == 0) {
        if (!holdsTempFile(out)) {
          continue;
        }
        ::kill(child.pid(), SIGSTOP);
        ::waitpid(child.pid(), &status, WUNTRACED);
        if (WIFSTOPPED(status) && holdsTempFile(out)) {
          caught = true;
          ::kill(child.pid(), signal);
        }
        ::kill(child.pid(), SIGCONT);
        if (caught) {
          break;
        }
      }
      if (!caught) {
        continue;  // the bake finished between two looks: try again
      }
      const int code = child.wait();
      EXPECT_EQ(code, 7) << child.err();
      EXPECT_FALSE(holdsTempFile(out)) << listing(out);
      EXPECT_FALSE(fs::exists(out + "/c.report.json")) << "a stopped bake wrote its report";
      for (const auto& entry : fs::directory_iterator(out)) {
        EXPECT_TRUE(isCompleteExr(entry.path().string())) << entry.path();
      }
    }
    EXPECT_TRUE(caught) << "never saw the bake write a frame";
  }
}

// ---- Defect 9: the database loader checks before it allocates, and checks everything ----

/// Where `"key": "` ends in the header of database `bytes` (the value's first character).
std::size_t headerValue(const std::string& bytes, const std::string& key) {
  const std::string text = "\"" + key + "\": \"";
  const std::size_t at = bytes.find(text, 24);
  EXPECT_NE(at, std::string::npos) << key;
  return at + text.size();
}

/// Database `bytes` as an editor who knows the format would leave them: every block checksum,
/// then (given) the content hash, then the whole file's checksum recomputed.
std::string resealed(std::string bytes, const std::string& contentHash = "") {
  std::uint64_t headerLength = 0;
  std::memcpy(&headerLength, bytes.data() + 16, 8);
  const nlohmann::json header = nlohmann::json::parse(bytes.substr(24, headerLength));
  for (const nlohmann::json& block : header.at("blocks")) {
    const auto offset = block.at("offset").get<std::size_t>();
    const auto size = block.at("bytes").get<std::size_t>();
    const std::string oldSum = block.at("fnv1a64").get<std::string>();
    const std::size_t at = bytes.find("\"" + oldSum + "\"", 24);
    bytes.replace(at + 1, 16, hashToHex(Hasher().add(bytes.data() + offset, size).value()));
  }
  if (!contentHash.empty()) {
    bytes.replace(headerValue(bytes, "content_hash"), 16, contentHash);
  }
  const std::size_t digits = headerValue(bytes, "file_fnv1a64");
  bytes.replace(digits, 16, std::string(16, '0'));
  bytes.replace(digits, 16, hashToHex(Hasher().add(bytes.data(), bytes.size()).value()));
  return bytes;
}

/// The float32 block `name` of database `bytes`: its offset and value count.
std::pair<std::size_t, std::size_t> floatBlock(const std::string& bytes, const std::string& name) {
  std::uint64_t headerLength = 0;
  std::memcpy(&headerLength, bytes.data() + 16, 8);
  const nlohmann::json header = nlohmann::json::parse(bytes.substr(24, headerLength));
  for (const nlohmann::json& block : header.at("blocks")) {
    if (block.at("name") == name) {
      return {block.at("offset").get<std::size_t>(), block.at("bytes").get<std::size_t>() / 4};
    }
  }
  ADD_FAILURE() << "no block " << name;
  return {0, 0};
}

// A non-database of gigabytes, or a header that claims 8 GiB, was read whole before any check
// (exit 1 out of memory under a limit): the prefix is checked against the file's size first.
TEST(CliSafety, DatabaseHeaderLengthIsCheckedBeforeAnythingIsAllocated) {
  TempDir dir;
  std::string prefix = "DSHAPEDB";
  const std::uint32_t version = 1, reserved = 0;
  const std::uint64_t headerLength = std::uint64_t{8} << 30;
  prefix.append(reinterpret_cast<const char*>(&version), 4);
  prefix.append(reinterpret_cast<const char*>(&reserved), 4);
  prefix.append(reinterpret_cast<const char*>(&headerLength), 8);
  const std::string huge = dir.file("huge.dsdb");
  writeText(huge, prefix + "{}");
  fs::resize_file(huge, (std::uint64_t{9} << 30));  // sparse: no disk used
  const std::string other = dir.file("other.dsdb");
  writeText(other, "not a database");
  fs::resize_file(other, (std::uint64_t{3} << 30));
  for (const std::string& path : {huge, other}) {
    SCOPED_TRACE(path);
    Child child(dir,
                {"bake", "--db", path, "--driver", sample("test.driver.pc2"), "--frames", "1", "-o",
                 dir.file("o.####.exr")},
                {{RLIMIT_AS, rlim_t{1} << 30}});
    EXPECT_EQ(child.wait(), 3) << child.err();
    EXPECT_NE(child.err().find(path), std::string::npos) << child.err();
  }
}

// The header had no checksum and its content hash was not compared: NaN driver shapes, a cycle
// of parts, a wrong block shape and an edited length_scale were accepted (NaN in a model block
// exited 6). Every one is an input error naming the file now; files of earlier versions, which
// have no checksum, still load.
TEST(CliSafety, DatabaseChecksumAndContentHashAreVerified) {
  TempDir dir;
  const std::string db = testing::buildPoseDb(dir);
  const std::string bytes = slurp(db);
  const auto load = [&](const std::string& content) {
    writeText(dir.file("edited.dsdb"), content);
    return runCli(dir, {"info", dir.file("edited.dsdb")});
  };
  EXPECT_EQ(load(bytes).code, 0);
  // A flipped byte in the padding after the header (no block covers it).
  std::uint64_t headerLength = 0;
  std::memcpy(&headerLength, bytes.data() + 16, 8);
  std::string padded = bytes;
  ASSERT_EQ(padded[24 + headerLength], '\0');
  padded[24 + headerLength] = 'x';
  expectError(load(padded), 3, "fails its checksum");
  // length_scale edited (same length), the checksums recomputed: the content hash differs.
  std::string edited = bytes;
  const std::size_t scale = edited.find("\"length_scale\": ");
  ASSERT_NE(scale, std::string::npos);
  const std::size_t digit = edited.find_first_of("123456789", scale + 16);
  edited[digit] = edited[digit] == '9' ? '8' : static_cast<char>(edited[digit] + 1);
  expectError(load(resealed(edited)), 3, "content hashes to");
  // Shapes and model blocks with NaN, a cycle of parts: the content hash recomputed too.
  Database loaded = loadDatabase(db);
  for (const char* name : {"driver_shapes", "model_basis"}) {
    SCOPED_TRACE(name);
    std::string poisoned = bytes;
    const auto [offset, count] = floatBlock(bytes, name);
    ASSERT_GT(count, 10u);
    const float nan = std::nanf("");
    std::memcpy(&poisoned[offset + 4 * 7], &nan, 4);
    Database same = loaded;
    std::vector<float>& values =
        std::string(name) == "driver_shapes" ? same.driverShapes : same.poseModel.basis;
    values[7] = nan;
    expectError(load(resealed(poisoned, hashToHex(same.contentHash()))), 3, name);
  }
  if (loaded.poseModel.parent.size() >= 2) {
    std::string cycle = bytes;
    const auto [offset, count] = floatBlock(bytes, "model_parent");
    const std::int32_t zero = 0, one = 1;
    std::memcpy(&cycle[offset], &one, 4);
    std::memcpy(&cycle[offset + 4], &zero, 4);
    Database same = loaded;
    same.poseModel.parent[0] = 1;
    same.poseModel.parent[1] = 0;
    expectError(load(resealed(cycle, hashToHex(same.contentHash()))), 3, "cycle");
  } else {
    ADD_FAILURE() << "the sample's pose model has one part; no cycle to make";
  }
  // A block shape that does not hold the block's values.
  std::string shaped = bytes;
  const std::size_t rest = shaped.find("\"name\": \"driven_rest\"");
  const std::size_t shape = shaped.find("\"shape\": [", rest);
  const std::size_t three = shaped.find("3\n", shape);
  ASSERT_LT(three, shaped.find(']', shape));
  shaped[three] = '4';
  expectError(load(resealed(shaped)), 3, "driven_rest");
  // A database of an earlier version (no whole-file checksum) loads.
  EXPECT_EQ(
      runCli(dir, {"info", testing::dataDir() + "/../fuzz/corpus/database/pose_model.dsdb"}).code,
      0);
}

// ---- Defect 7: a resume removes only its own frames' temporary files ----

// With output names past 233 bytes, every frame's temporary name was cut to the same prefix, so
// a resumed chunk deleted the file another chunk was writing; and any `.<frame>.tmp-*` was
// deleted, a user's notes too. A long name's temporary prefix now carries a hash of the whole
// name, and only names with exactly 16 hex digits after the prefix are temporary files.
TEST(CliSafety, ResumeKeepsAnotherChunksTemporaryFileAndUsersFiles) {
  TempDir dir;
  const std::string db = buildDb(dir);
  const std::string out = dir.file("shot");
  fs::create_directory(out);
  const std::string pattern = out + "/" + std::string(236, 'c') + ".####.exr";
  ASSERT_GT(fs::path(expandFramePattern(pattern, 1)).filename().string().size(), 233u);
  // Chunk 1 (frame 2) is being written by another task while chunk 0 (frame 1) resumes.
  AtomicFile other(expandFramePattern(pattern, 2));
  other.stream() << "frame 2, half written";
  ASSERT_TRUE(fs::exists(other.tempPath()));
  // Files of the user's named like temporary files of frame 1, but not exactly so.
  const std::vector<std::string> notTemp = {out + "/.cloth.0001.exr.tmp-notes",
                                            out + "/.cloth.0001.exr.tmp-0123456789abcdeg",
                                            out + "/.cloth.0001.exr.tmp-0123456789abcdef0"};
  for (const std::string& name : notTemp) {
    writeText(name, "the user's own file");
  }
  const std::string stale = out + "/.cloth.0001.exr.tmp-0123456789abcdef";
  writeText(stale, "half a frame of a killed run");
  CliRun r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames",
                          "1-2", "--chunk-size", "1", "--chunk-index", "0", "--skip-existing",
                          "--quiet", "-o", pattern});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(other.tempPath())) << "another chunk's temporary file was removed";
  other.commit(false);
  EXPECT_EQ(slurp(expandFramePattern(pattern, 2)), "frame 2, half written");
  r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1-2",
                   "--skip-existing", "--quiet", "-o", out + "/cloth.####.exr"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(fs::exists(stale)) << "a killed run's temporary file was kept";
  for (const std::string& name : notTemp) {
    EXPECT_EQ(slurp(name), "the user's own file") << name;
  }
}

// ---- Defect 10: huge finite values are refused up front, never an internal error ----

/// `source` (a PC2) with every coordinate times `scale`, written to `path`.
std::string scaledPc2(const std::string& source, const std::string& path, float scale) {
  std::string bytes = slurp(source);
  for (std::size_t at = 32; at + 4 <= bytes.size(); at += 4) {
    float value = 0;
    std::memcpy(&value, &bytes[at], 4);
    value *= scale;
    std::memcpy(&bytes[at], &value, 4);
  }
  writeText(path, bytes);
  return path;
}

// `--skin-offset 1e30` ended in exit 1 "closest triangle ... (a bug)" on the host path; a 1e30
// driver with --force in exit 6 (or 1), and a database built from a 1e30 --also clip too.
TEST(CliSafety, HugeFiniteValuesAreUsageOrInputErrors) {
  TempDir dir;
  const std::string db = buildDb(dir);
  std::vector<std::string> bake = {
      "bake",    "--db",     db,     "--driver", sample("test.driver.pc2"), "--frames", "1-2",
      "--quiet", "--device", "host", "-o",       dir.file("o.####.exr")};
  CliRun r = runCli(dir, with(bake, {"--skin-offset", "1e30"}));
  expectError(r, 2, "--skin-offset");
  // The message names the bound the value breaks, not the one it meets.
  EXPECT_NE(r.err.find("<= 1e+06"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("must be a number >= 0"), std::string::npos) << r.err;
  expectError(runCli(dir, with(bake, {"--exit-fade", "-1"})), 2, "must be a number >= 0");

  const std::string huge = scaledPc2(sample("test.driver.pc2"), dir.file("huge.pc2"), 1e30f);
  bake[4] = huge;
  expectError(runCli(dir, with(bake, {"--force"})), 3, "huge.pc2' frame 1 vertex");
  const std::string hugeClip = scaledPc2(sample("test.driven.pc2"), dir.file("clip.pc2"), 1e30f);
  expectError(
      runCli(dir, sampleDbBuild({"--count", "3", "--quiet", "--also", sample("test.driver.pc2"),
                                 hugeClip, "-o", dir.file("x.dsdb")})),
      3, "clip.pc2");
  EXPECT_FALSE(fs::exists(dir.file("o.0001.exr")));
  EXPECT_FALSE(fs::exists(dir.file("x.dsdb")));
}

// `db build --also` took a clip in other units (a 61 m model error): every clip's caches, the
// main clip's too, are measured against the rest meshes (median edge length).
TEST(CliSafety, DbBuildRefusesAClipInOtherUnits) {
  TempDir dir;
  const std::vector<std::string> build =
      sampleDbBuild({"--count", "3", "--quiet", "-o", dir.file("x.dsdb")});
  const std::string driverCm = scaledPc2(sample("test.driver.pc2"), dir.file("cm.pc2"), 100.0f);
  const std::string drivenCm = scaledPc2(sample("test.driven.pc2"), dir.file("cmd.pc2"), 100.0f);
  expectError(runCli(dir, with(build, {"--also", driverCm, drivenCm})), 3,
              "cm.pc2' (reference clip 2) frame 1 is 100");
  expectError(runCli(dir, with(build, {"--also", sample("test.driver.pc2"), drivenCm})), 3,
              "cmd.pc2' (reference clip 2) frame 1 is 100.0");
  std::vector<std::string> main = build;
  main[7] = driverCm;
  main[9] = drivenCm;
  expectError(runCli(dir, main), 3, "(the main reference clip)");
  EXPECT_FALSE(fs::exists(dir.file("x.dsdb")));
  // Within a few percent (a clip of the same character in the same units) is built.
  const std::string slightly = scaledPc2(sample("test.driven.pc2"), dir.file("near.pc2"), 1.03f);
  EXPECT_EQ(runCli(dir, with(build, {"--also", sample("test.driver.pc2"), slightly})).code, 0);
}

// ---- Defect list, medium and low ----

// `--frames 1-10000000` took 30-80 s and 2.7 GB before "no frame 49"; `-o out/####/c.exr` made a
// literal folder per frame; a bad --report was refused only after the -o folder was made (a
// folder as --report only after the whole bake).
TEST(CliSafety, BadFramesPatternsAndReportsAreRefusedBeforeAnythingIsMade) {
  TempDir dir;
  const std::string db = buildDb(dir);
  const auto start = std::chrono::steady_clock::now();
  Child child(dir,
              {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1-10000000",
               "--quiet", "-o", dir.file("new/o.####.exr")},
              {{RLIMIT_AS, rlim_t{1} << 30}});
  EXPECT_EQ(child.wait(), 3) << child.err();
  EXPECT_NE(child.err().find("has no frame 49"), std::string::npos) << child.err();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);

  const std::vector<std::string> bake = {
      "bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1-2", "--quiet"};
  expectError(runCli(dir, with(bake, {"-o", dir.file("out/####/c.exr")})), 2, "folder name");
  fs::create_directory(dir.file("report-folder"));
  expectError(runCli(dir, with(bake, {"-o", dir.file("new/o.####.exr"), "--report",
                                      dir.file("report-folder")})),
              4, "is a folder");
  writeText(dir.file("not-a-folder"), "a file");
  expectError(runCli(dir, with(bake, {"-o", dir.file("new/o.####.exr"), "--report",
                                      dir.file("not-a-folder/r.json")})),
              4, "not-a-folder");
  EXPECT_FALSE(fs::exists(dir.file("new"))) << "the -o folder was made before a refusal";
  EXPECT_FALSE(fs::exists(dir.file("out")));
}

// Rig files with a self-parent, an unknown parent or a vertex without weight were accepted.
TEST(CliSafety, RigFilesWithBadParentsOrNoWeightAreInputErrors) {
  TempDir dir;
  const int vertices = readObj(sample("driver_rest.obj")).vertexCount();
  const auto rig = [&](const std::string& bones, const std::string& lastRow) {
    std::string text =
        R"({"bone_names": ["root", "arm"], "bones": )" + bones + R"(, "driver_weights": [)";
    for (int v = 0; v + 1 < vertices; ++v) {
      text += v % 2 == 0 ? "[1, 0]," : "[0.2, 0.8],";
    }
    writeText(dir.file("rig.json"), text + lastRow + "]}");
    return runCli(dir, sampleDbBuild({"--count", "3", "--quiet", "--rig", dir.file("rig.json"),
                                      "-o", dir.file("x.dsdb")}));
  };
  const std::string bones = R"([{"name": "root", "parent": null}, {"name": "arm", "parent": )";
  expectError(rig(bones + R"("arm"}])", "[1, 0]"), 3, "bone 'arm' is its own parent");
  expectError(rig(bones + R"("hips"}])", "[1, 0]"), 3, "the parent 'hips' of bone 'arm'");
  expectError(rig(bones + R"("root"}])", "[0, 0]"), 3,
              "row " + std::to_string(vertices - 1) + " has no positive weight");
  EXPECT_FALSE(fs::exists(dir.file("x.dsdb")));
  const CliRun good = rig(bones + R"("root"}])", "[1, 0]");
  EXPECT_EQ(good.code, 0) << good.err;
  // A parent that deforms nothing (no column of weights), as the clip generator's `root`.
  const CliRun unweighted =
      rig(R"([{"name": "world", "parent": null}, {"name": "root", "parent": "world"}, )"
          R"({"name": "arm", "parent": "root"}])",
          "[1, 0]");
  EXPECT_EQ(unweighted.code, 0) << unweighted.err;
}

// `eval --report` took `"database": null` for a report; `farm --time 99:99:99` was accepted.
TEST(CliSafety, DamagedReportFieldsAndTimeFieldsAreRefused) {
  TempDir dir;
  writeText(dir.file("report.json"), R"({"database": null, "frames": [{"frame": 1}]})");
  expectError(runCli(dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake",
                           sample("test.driven.pc2"), "--frames", "1", "--report",
                           dir.file("report.json")}),
              3, "database is null");
  const std::string db = buildDb(dir);
  for (const char* time : {"99:99:99", "10:60", "1-24:00:00"}) {
    SCOPED_TRACE(time);
    expectError(runCli(dir, {"farm", "slurm", "--db", db, "--driver", sample("test.driver.pc2"),
                             "--frames", "1-4", "-o", dir.file("c.####.exr"), "--chunk-size", "2",
                             "--time", time, "-O", dir.file("job.sbatch")}),
                2, "is past");
  }
  EXPECT_FALSE(fs::exists(dir.file("job.sbatch")));
}

// Outputs are created with the user's umask like any other tool's files (0644 under 022).
TEST(CliSafety, OutputsFollowTheUmask) {
  TempDir dir;
  const mode_t before = ::umask(022);
  const std::string db = buildDb(dir);
  const CliRun r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"),
                                "--frames", "1", "--quiet", "-o", dir.file("o.####.exr")});
  ::umask(before);
  ASSERT_EQ(r.code, 0) << r.err;
  for (const std::string& file : {db, dir.file("o.0001.exr"), dir.file("o.report.json")}) {
    struct stat status {};
    ASSERT_EQ(::stat(file.c_str(), &status), 0) << file;
    EXPECT_EQ(status.st_mode & 0777, 0644u) << file;
  }
}

}  // namespace
}  // namespace drivenshape
