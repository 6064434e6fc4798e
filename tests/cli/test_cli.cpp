// SPDX-License-Identifier: Apache-2.0
// The command line as users run it: a real process, real files, exit codes and messages.
// Every bad input must give a one-line error naming the file (or flag) and a documented exit
// code, and must leave no partial output behind.

#include <gtest/gtest.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>

#include <unistd.h>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/settings_table.h>

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

TEST(Cli, HelpForEveryCommand) {
  TempDir dir;
  for (const std::vector<std::string>& words : {std::vector<std::string>{"--help"},
                                                {"devices", "--help"},
                                                {"info", "--help"},
                                                {"db", "build", "--help"},
                                                {"bake", "--help"},
                                                {"eval", "--help"}}) {
    const CliRun r = runCli(dir, words);
    EXPECT_EQ(r.code, 0) << words[0];
    EXPECT_NE(r.out.find("usage"), std::string::npos) << r.out;
  }
  EXPECT_NE(runCli(dir, {"bake", "--help"}).out.find("Exit codes"), std::string::npos);
}

TEST(Cli, UsageErrorsExitWithTwo) {
  TempDir dir;
  expectError(runCli(dir, {"bake", "--bogus"}), 2, "--bogus");
  expectError(runCli(dir, {"frobnicate"}), 2, "frobnicate");
  expectError(runCli(dir, {"bake", "--db", "x"}), 2, "missing required option");
  expectError(runCli(dir, {"db", "build", "--driver-mesh", "a", "--driven-mesh", "b", "--driver",
                           "c", "--driven", "d", "-o", dir.file("db"), "--count", "zero"}),
              2, "--count");
  const std::vector<std::string> build{
      "db", "build", "--driver-mesh", "a", "--driven-mesh", "b", "--driver", "c", "--driven",
      "d",  "-o",    dir.file("db")};
  const auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = build;
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  };
  expectError(runCli(dir, with({"--model-rank", "0"})), 2, "--model-rank");
  expectError(runCli(dir, with({"--model-velocity", "-1"})), 2, "--model-velocity");
  expectError(runCli(dir, with({"--model-history", "500"})), 2, "--model-history");
  for (const char* weight : {"sometimes", "-1", "5000"}) {
    expectError(runCli(dir, with({"--model-per-clip", weight})), 2, "--model-per-clip");
  }
}

TEST(Cli, DevicesListsTheOpenClDevice) {
  TempDir dir;
  const CliRun r = runCli(dir, {"devices"});
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("0: "), std::string::npos) << "no OpenCL device listed: " << r.out;
}

TEST(Cli, EndToEndBuildBakeEvalInfo) {
  TempDir dir;
  const std::string db = buildDb(dir);
  CliRun r = runCli(dir, {"info", db});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("5 shapes"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("seed"), std::string::npos) << r.out;
  // The sleeve is cloth: every driven vertex outside.
  EXPECT_NE(r.out.find("side table: 0 of 2244 driven vertices live inside"), std::string::npos)
      << r.out;

  fs::create_directories(dir.file("out"));
  r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1-10x3",
                   "-o", dir.file("out/sleeve.####.exr"), "--device", "0"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("outputs: "), std::string::npos);
  for (int frame : {1, 4, 7, 10}) {
    char name[64];
    std::snprintf(name, sizeof(name), "out/sleeve.%04d.exr", frame);
    EXPECT_TRUE(fs::exists(dir.file(name))) << name;
  }
  EXPECT_TRUE(fs::exists(dir.file("out/sleeve.report.json")));
  EXPECT_NE(r.err.find("ALF_PROGRESS 100%"), std::string::npos) << r.err;

  r = runCli(
      dir, {"eval", "--truth", sample("test.driven.pc2"), "--bake", dir.file("out/sleeve.####.exr"),
            "--frames", "1-10x3", "--json", dir.file("eval.json")});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("rms"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir.file("eval.json")));

  r = runCli(dir, {"info", dir.file("out/sleeve.0004.exr")});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("2244 vertices"), std::string::npos) << r.out;
}

TEST(Cli, BakeFidelityFlagsAreDocumentedAndBadGroupsAreInputErrors) {
  TempDir dir;
  CliRun r = runCli(dir, {"bake", "--help"});
  ASSERT_EQ(r.code, 0);
  for (const char* flag : {"--align", "--align-group", "--blend", "--skin-offset", "--no-resolve",
                           "--regions", "--max-weight-change", "--temporal-warmup"}) {
    EXPECT_NE(r.out.find(flag), std::string::npos) << flag;
  }
  const std::string db = buildDb(dir);
  const std::vector<std::string> bake = {"bake",
                                         "--db",
                                         db,
                                         "--driver",
                                         sample("test.driver.pc2"),
                                         "--frames",
                                         "1-6",
                                         "-o",
                                         dir.file("out.####.exr")};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = bake;
    args.insert(args.end(), extra.begin(), extra.end());
    return runCli(dir, args);
  };
  // Unknown group, too few vertices: input errors (3) naming the flag; nothing written.
  expectError(with({"--align-group", "left_leg"}), 3, "no group 'left_leg' (its groups: arm)");
  expectError(with({"--align-group", "0,1"}), 3, "at least 3 non-collinear");
  std::ofstream(dir.file("bad.json"))
      << R"({"regions": [{"name": "left", "driver": ["left_leg"], "driven": "sleeve"}]})";
  expectError(with({"--regions", dir.file("bad.json")}), 3, "regions[0].driver");
  expectError(with({"--regions", dir.file("missing.json")}), 3, "missing.json");
  EXPECT_TRUE(filesIn(dir.path()).size() == 2u) << "outputs left behind";  // db + bad.json
  // Usage errors (2).
  expectError(with({"--align", "sideways"}), 2, "--align");
  expectError(with({"--blend", "local", "--no-correct"}), 2, "--blend local");
  expectError(with({"--max-weight-change", "0.1", "--chunk-size", "5", "--chunk-index", "0",
                    "--batch", "3"}),
              2, "multiple of --batch");
  // Everything together works and lands in the report.
  std::ofstream(dir.file("regions.json"))
      << R"({"falloff": 2, "regions": [{"name": "top", "driver": {"vertices": ["0-999"]},
             "driven": {"vertices": ["0-1099"]}}]})";
  r = with({"--align-group", "arm", "--blend", "local", "--regions", dir.file("regions.json"),
            "--max-weight-change", "0.1", "--temporal-warmup", "2", "--skin-offset", "0.001",
            "--report", dir.file("report.json")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("after resolution"), std::string::npos) << r.out;
  const std::string report = slurp(dir.file("report.json"));
  for (const char* key :
       {"\"align\": \"rigid\"", "\"blend\": \"local\"", "\"max_weight_change\": 0.1",
        "\"skin_offset\": 0.001", "\"name\": \"rest\"", "\"inside_corrected\""}) {
    EXPECT_NE(report.find(key), std::string::npos) << key;
  }
}

TEST(Cli, TruncatedPc2IsAnInputError) {
  TempDir dir;
  const std::string db = buildDb(dir);
  const std::string full = slurp(sample("test.driver.pc2"));
  std::ofstream(dir.file("cut.pc2"), std::ios::binary) << full.substr(0, full.size() - 1000);
  fs::create_directories(dir.file("out"));
  const CliRun r = runCli(dir, {"bake", "--db", db, "--driver", dir.file("cut.pc2"), "--frames",
                                "1-3", "-o", dir.file("out/x.####.exr")});
  expectError(r, 3, "cut.pc2");
  EXPECT_TRUE(filesIn(dir.file("out")).empty());
}

TEST(Cli, ObjWithOutOfRangeIndexIsAnInputError) {
  TempDir dir;
  std::ofstream(dir.file("bad.obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n";
  const CliRun r =
      runCli(dir, {"db", "build", "--driver-mesh", dir.file("bad.obj"), "--driven-mesh",
                   sample("driven_rest.obj"), "--driver", sample("train.driver.pc2"), "--driven",
                   sample("train.driven.pc2"), "-o", dir.file("db.dsdb")});
  expectError(r, 3, "bad.obj");
  EXPECT_FALSE(fs::exists(dir.file("db.dsdb")));
}

TEST(Cli, BadExrDriverCachesAreInputErrors) {
  TempDir dir;
  const std::string db = buildDb(dir);
  const Mesh driver = readObj(sample("driver_rest.obj"));
  const auto cache = openPointCache(sample("test.driver.pc2"));
  std::vector<float> xyz(cache->vertexCount() * 3);
  cache->readFrame(1, xyz.data());
  fs::create_directories(dir.file("out"));

  // Wrong vertex count.
  fs::create_directories(dir.file("count"));
  ExrWriteOptions options;
  options.frame = 1;
  options.topologyHash = topologyHash(cache->vertexCount() - 10);
  writePointCacheExr(dir.file("count/drv.0001.exr"), cache->vertexCount() - 10, xyz.data(), nullptr,
                     options);
  expectError(runCli(dir, {"bake", "--db", db, "--driver", dir.file("count/drv.####.exr"),
                           "--frames", "1", "-o", dir.file("out/x.####.exr")}),
              3, "drv.");

  // Right count, another topology.
  fs::create_directories(dir.file("topo"));
  options.topologyHash = 0x0123456789abcdefULL;
  writePointCacheExr(dir.file("topo/drv.0001.exr"), cache->vertexCount(), xyz.data(), nullptr,
                     options);
  expectError(runCli(dir, {"bake", "--db", db, "--driver", dir.file("topo/drv.####.exr"),
                           "--frames", "1", "-o", dir.file("out/x.####.exr")}),
              3, "topology");

  // Missing P.Y channel.
  fs::create_directories(dir.file("chan"));
  {
    const int width = 1024, height = (cache->vertexCount() + width - 1) / width;
    Imf::Header header(width, height);
    header.channels().insert("P.X", Imf::Channel(Imf::FLOAT));
    header.channels().insert("P.Z", Imf::Channel(Imf::FLOAT));
    header.insert("dsVertexCount", Imf::IntAttribute(cache->vertexCount()));
    header.insert("dsFrame", Imf::IntAttribute(1));
    Imf::OutputFile file(dir.file("chan/drv.0001.exr").c_str(), header);
    std::vector<float> zeros(static_cast<std::size_t>(width) * height, 0.0f);
    Imf::FrameBuffer buffer;
    buffer.insert("P.X", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(zeros.data()),
                                    sizeof(float), sizeof(float) * width));
    buffer.insert("P.Z", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(zeros.data()),
                                    sizeof(float), sizeof(float) * width));
    file.setFrameBuffer(buffer);
    file.writePixels(height);
  }
  expectError(runCli(dir, {"bake", "--db", db, "--driver", dir.file("chan/drv.####.exr"),
                           "--frames", "1", "-o", dir.file("out/x.####.exr")}),
              3, "P.Y");
  EXPECT_TRUE(filesIn(dir.file("out")).empty());
}

TEST(Cli, EmptyFrameRangeIsAUsageError) {
  TempDir dir;
  const std::string db = buildDb(dir);
  fs::create_directories(dir.file("out"));
  for (const std::string range : {"", "10-1", "1-10x0", "abc"}) {
    const CliRun r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"),
                                  "--frames", range, "-o", dir.file("out/x.####.exr")});
    EXPECT_EQ(r.code, 2) << "range '" << range << "': " << r.err;
  }
  EXPECT_TRUE(filesIn(dir.file("out")).empty());
}

TEST(Cli, DriverOfAnotherCharacterIsAnInputError) {
  TempDir dir;
  const std::string db = buildDb(dir);
  fs::create_directories(dir.file("out"));
  // The driven cache has another vertex count than the database's driver.
  const CliRun r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driven.pc2"),
                                "--frames", "1-3", "-o", dir.file("out/x.####.exr")});
  expectError(r, 3, "test.driven.pc2");
  EXPECT_NE(r.err.find("2146"), std::string::npos) << r.err;
  EXPECT_TRUE(filesIn(dir.file("out")).empty());
}

TEST(Cli, BakeAndPosmapCreateMissingOutputFoldersAndSaySo) {
  TempDir dir;
  const std::string db = buildDb(dir);
  CliRun r =
      runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1-2",
                   "-o", dir.file("shot/v001/x.####.exr"), "--report", dir.file("reports/x.json"),
                   "--posmap", "16", "--posmap-out", dir.file("maps/m.####.exr")});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* folder : {"shot", "shot/v001", "reports", "maps"}) {
    EXPECT_NE(r.err.find("created folder " + dir.file(folder) + "\n"), std::string::npos)
        << folder << " in: " << r.err;
  }
  EXPECT_EQ(filesIn(dir.file("shot/v001")).size(), 2u);
  EXPECT_TRUE(fs::is_regular_file(dir.file("reports/x.json")));
  EXPECT_EQ(filesIn(dir.file("maps")).size(), 2u);
  r = runCli(dir, {"posmap", "--mesh", sample("driven_rest.obj"), "--cache",
                   dir.file("shot/v001/x.####.exr"), "--frames", "1-2", "--res", "16", "-o",
                   dir.file("posmaps/p.####.exr")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("created folder " + dir.file("posmaps")), std::string::npos) << r.err;
  EXPECT_EQ(filesIn(dir.file("posmaps")).size(), 2u);
}

TEST(Cli, BakeVerboseNamesEverySettingEachFrameAndTheStages) {
  TempDir dir;
  const std::string db = buildPoseDb(dir);  // db build's defaults: the pose model
  CliRun r =
      runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1-3",
                   "-o", dir.file("v/x.####.exr"), "--verbose", "--exit-fade", "0.1"});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const Setting& setting : settingsTable()) {
    if (setting.flag != nullptr && (hasEvaluatorValue(setting) || hasBakeValue(setting))) {
      EXPECT_NE(r.err.find("\n  " + std::string(setting.label) + " "), std::string::npos)
          << setting.label << " in: " << r.err;
    }
  }
  // The one setting given is marked with the documented default (docs/commands.md).
  EXPECT_NE(r.err.find("exit fade               0.1  (default 0.25)\n"), std::string::npos)
      << r.err;
  for (int frame = 1; frame <= 3; ++frame) {
    EXPECT_NE(r.err.find("frame " + std::to_string(frame) + " baked in "), std::string::npos)
        << r.err;
  }
  EXPECT_NE(r.err.find(", predicted error "), std::string::npos) << "the pose model's: " << r.err;
  EXPECT_NE(r.err.find(", bound "), std::string::npos) << "the verdict's bound: " << r.err;
  EXPECT_NE(r.err.find("seconds: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(" resolve "), std::string::npos) << r.err;
  r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1", "-o",
                   dir.file("v/y.####.exr"), "--verbose", "--quiet"});
  expectError(r, 2, "--quiet and --verbose");
}

TEST(Cli, UnwritableOutputFolderIsAnOutputError) {
  TempDir dir;
  const std::string db = buildDb(dir);
  // A file where the output folder should be: nothing is created or written.
  std::ofstream(dir.file("plain")) << "x";
  CliRun r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames",
                          "1-3", "-o", dir.file("plain/sub/x.####.exr")});
  expectError(r, 4, "plain/sub");
  EXPECT_EQ(fs::file_size(dir.file("plain")), 1u);
  // A read-only folder (only meaningful when not root: root writes anywhere).
  fs::create_directories(dir.file("ro"));
  fs::permissions(dir.file("ro"), fs::perms::owner_read | fs::perms::owner_exec);
  if (::access(dir.file("ro").c_str(), W_OK) != 0) {
    r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "1-3",
                     "-o", dir.file("ro/x.####.exr")});
    expectError(r, 4, "not writable");
  }
  fs::permissions(dir.file("ro"), fs::perms::owner_all);
  EXPECT_TRUE(filesIn(dir.file("ro")).empty());
}

/// The position and coverage planes of a position map (R, G, B, A; with `legacy`, P.X, P.Y,
/// P.Z, A), concatenated. A missing channel fails the test (OpenEXR would fill it with zeros).
std::vector<float> exrPlanes(const std::string& path, bool legacy = false) {
  Imf::InputFile file(path.c_str());
  const Imath::Box2i window = file.header().dataWindow();
  const int width = window.max.x - window.min.x + 1, height = window.max.y - window.min.y + 1;
  std::vector<float> planes(static_cast<std::size_t>(width) * height * 4);
  Imf::FrameBuffer buffer;
  const char* rgba[] = {"R", "G", "B", "A"};
  const char* former[] = {"P.X", "P.Y", "P.Z", "A"};
  const char* const* names = legacy ? former : rgba;
  for (int c = 0; c < 4; ++c) {
    EXPECT_NE(file.header().channels().findChannel(names[c]), nullptr) << names[c] << " " << path;
    char* base = reinterpret_cast<char*>(&planes[static_cast<std::size_t>(c) * width * height]) -
                 (static_cast<std::ptrdiff_t>(window.min.y) * width + window.min.x) *
                     static_cast<std::ptrdiff_t>(sizeof(float));
    buffer.insert(names[c], Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * width));
  }
  file.setFrameBuffer(buffer);
  file.readPixels(window.min.y, window.max.y);
  return planes;
}

TEST(Cli, BakePosmapEqualsPosmapOfTheBakedCache) {
  TempDir dir;
  const std::string db = buildDb(dir);
  fs::create_directories(dir.file("out"));
  CliRun r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames",
                          "5-7", "-o", dir.file("out/s.####.exr"), "--posmap", "96x64", "--quiet"});
  ASSERT_EQ(r.code, 0) << r.err;
  r = runCli(dir,
             {"posmap", "--mesh", sample("driven_rest.obj"), "--cache", dir.file("out/s.####.exr"),
              "--frames", "5-7", "--res", "96x64", "-o", dir.file("out/alone.####.exr")});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* frame : {"0005", "0006", "0007"}) {
    const std::vector<float> inBake =
        exrPlanes(dir.file(std::string("out/s.posmap.") + frame + ".exr"));
    const std::vector<float> alone =
        exrPlanes(dir.file(std::string("out/alone.") + frame + ".exr"));
    EXPECT_EQ(inBake, alone) << "frame " << frame;
    EXPECT_GT(std::count(inBake.begin() + 3 * 96 * 64, inBake.end(), 1.0f), 100)
        << "the map covers texels";
  }
  // `info` tells a position map from a point cache and describes it.
  r = runCli(dir, {"info", dir.file("out/alone.0006.exr")});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("position-map EXR"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("96x64 texels, frame 6"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("mesh of 2244 vertices"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("channels (rgba): R G B = position, A = coverage\n"), std::string::npos)
      << r.out;

  // The former channel names, on request, from `posmap` and from `bake --posmap`.
  r = runCli(dir, {"posmap", "--mesh", sample("driven_rest.obj"), "--cache",
                   dir.file("out/s.####.exr"), "--frames", "6", "--res", "96x64", "--channels",
                   "legacy", "--normals", "-o", dir.file("out/legacy.####.exr")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(exrPlanes(dir.file("out/legacy.0006.exr"), true),
            exrPlanes(dir.file("out/alone.0006.exr")));
  r = runCli(dir, {"info", dir.file("out/legacy.0006.exr")});
  EXPECT_NE(r.out.find("channels (legacy): P.X P.Y P.Z = position, A = coverage, N.X N.Y N.Z = "
                       "normals\n"),
            std::string::npos)
      << r.out;
  r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "6", "-o",
                   dir.file("out/l.####.exr"), "--posmap", "96x64", "--posmap-channels", "legacy",
                   "--quiet"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(exrPlanes(dir.file("out/l.posmap.0006.exr"), true),
            exrPlanes(dir.file("out/alone.0006.exr")));
  r = runCli(dir, {"bake", "--db", db, "--driver", sample("test.driver.pc2"), "--frames", "6", "-o",
                   dir.file("out/l.####.exr"), "--posmap", "96x64", "--posmap-channels", "xyz",
                   "--quiet"});
  expectError(r, 2, "--posmap-channels 'xyz' is not a channel naming");
}

TEST(Cli, ZipEncodersWriteTheSamePixelsAndABadOneIsAUsageError) {
  TempDir dir;
  const std::string db = buildDb(dir);
  fs::create_directories(dir.file("out"));
  EXPECT_NE(runCli(dir, {"bake", "--help"}).out.find("--zip-encoder"), std::string::npos);
  EXPECT_NE(runCli(dir, {"posmap", "--help"}).out.find("--zip-encoder"), std::string::npos);
  const std::vector<std::string> bake = {
      "bake",     "--db", db,        "--driver", sample("test.driver.pc2"),
      "--frames", "2-3",  "--quiet", "--posmap", "64"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = bake;
    args.insert(args.end(), extra.begin(), extra.end());
    return runCli(dir, args);
  };
  CliRun r = with({"-o", dir.file("out/fast.####.exr")});
  ASSERT_EQ(r.code, 0) << r.err;
  r = with({"-o", dir.file("out/zlib.####.exr"), "--zip-encoder", "openexr"});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* frame : {"0002", "0003"}) {
    std::vector<float> fast, zlib;
    const ExrPointCacheInfo info =
        readPointCacheExr(dir.file(std::string("out/fast.") + frame + ".exr"), fast);
    readPointCacheExr(dir.file(std::string("out/zlib.") + frame + ".exr"), zlib);
    EXPECT_EQ(info.compression, ExrCompression::kZip);
    ASSERT_EQ(fast.size(), zlib.size());
    EXPECT_EQ(std::memcmp(fast.data(), zlib.data(), fast.size() * sizeof(float)), 0) << frame;
    EXPECT_NE(slurp(dir.file(std::string("out/fast.") + frame + ".exr")),
              slurp(dir.file(std::string("out/zlib.") + frame + ".exr")))
        << "libdeflate and zlib make other deflate streams";
    EXPECT_EQ(exrPlanes(dir.file(std::string("out/fast.posmap.") + frame + ".exr")),
              exrPlanes(dir.file(std::string("out/zlib.posmap.") + frame + ".exr")));
  }
  const std::size_t before = filesIn(dir.file("out")).size();
  // The bake's settings are checked by the settings table, which names the flag and the value.
  expectError(with({"-o", dir.file("out/bad.####.exr"), "--zip-encoder", "zlib"}), 2,
              "--zip-encoder) takes libdeflate, openexr (got 'zlib')");
  expectError(runCli(dir, {"posmap", "--mesh", sample("driven_rest.obj"), "--cache",
                           dir.file("out/fast.####.exr"), "--frames", "2", "--res", "64", "-o",
                           dir.file("out/m.####.exr"), "--zip-encoder", "fast"}),
              2, "--zip-encoder 'fast'");
  EXPECT_EQ(filesIn(dir.file("out")).size(), before) << "a usage error writes nothing";
}

}  // namespace
}  // namespace drivenshape
