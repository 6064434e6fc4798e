// SPDX-License-Identifier: Apache-2.0
// `drivenshape db build` with more reference clips (--also) and frame suggestions (--suggest),
// run as users run it: the real binary, the sample's caches, exit codes and one-line errors.

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include <drivenshape/database.h>

#include "cli_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using testing::CliRun;
using testing::expectError;
using testing::filesIn;
using testing::runCli;
using testing::sample;
using testing::sampleDbBuild;
using testing::slurp;
using testing::TempDir;

/// db build of the sample's train clip with `extra` words.
CliRun build(const TempDir& dir, const std::vector<std::string>& extra) {
  return runCli(dir, sampleDbBuild(extra));
}

/// The frame numbers of the suggestion lines on stdout ("  1  frame     34  ...").
std::vector<int> suggestedFrames(const std::string& out) {
  std::vector<int> frames;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream words(line);
    int order = 0, frame = 0;
    std::string word;
    if (words >> order >> word >> frame && word == "frame") {
      frames.push_back(frame);
    }
  }
  return frames;
}

TEST(DbBuild, AlsoFitsTheModelOnMoreClipsAndKeepsThePicks) {
  TempDir dir;
  CliRun r = build(dir, {"-o", dir.file("one.dsdb")});
  ASSERT_EQ(r.code, 0) << r.err;
  r = build(dir, {"--also", sample("test.driver.pc2"), sample("test.driven.pc2") + ":1-24", "-o",
                  dir.file("two.dsdb"), "--model-json", dir.file("two.json")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("reference clip 2: '" + sample("test.driver.pc2")), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("fitted on the main clip alone (its own kernel settings): "),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("    without clip 1 (61 frames):  clip 1 "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("    without clip 2 (24 frames):  clip 1 "), std::string::npos) << r.err;
  // --model-json: the fit, every reference frame, the clips and what each adds; the verdict's
  // level as asked (0.92 by default) and its margin as the database holds it.
  const nlohmann::json fit = nlohmann::json::parse(slurp(dir.file("two.json")));
  EXPECT_EQ(fit["reference_frames"].get<int>(), 61 + 24);
  EXPECT_EQ(fit["frames"].size(), 85u);
  ASSERT_EQ(fit["clips"].size(), 2u);
  EXPECT_EQ(fit["clips"][1]["frames"].get<int>(), 24);
  EXPECT_EQ(fit["clips"][1]["errors_without_it"].size(), 2u);
  EXPECT_TRUE(fit["frames"][70].contains("left_out_error"));
  EXPECT_EQ(fit["verdict"]["level"].get<double>(), 0.92);
  const Database one = loadDatabase(dir.file("one.dsdb"));
  const Database two = loadDatabase(dir.file("two.dsdb"));
  EXPECT_EQ(fit["verdict"]["margin"].get<double>(), two.poseModel.verdictMargin);
  // The verdict's outlook: its smallest bound, and per tolerance the share of the frames it was
  // calibrated on (each clip left out) whose bound is within it, recounted from the frames.
  const double bias = fit["error_line"]["bias"], scale = fit["error_line"]["scale"];
  const double margin = fit["verdict"]["margin"];
  EXPECT_DOUBLE_EQ(fit["verdict"]["smallest_bound"].get<double>(), std::max(0.0, bias) + margin);
  ASSERT_EQ(fit["verdict"]["held_out_enough"].size(), 4u);
  for (const nlohmann::json& outlook : fit["verdict"]["held_out_enough"]) {
    const double tolerance = outlook["tolerance"];
    int within = 0;
    for (const nlohmann::json& frame : fit["frames"]) {
      const double sigma = frame["left_out_sigma"];
      within += std::max(0.0, bias + scale * sigma) + margin <= tolerance;
    }
    EXPECT_DOUBLE_EQ(outlook["enough"].get<double>(), within / 85.0) << outlook.dump();
  }
  EXPECT_EQ(fit["verdict"]["held_out_enough"][2]["tolerance_share"].get<double>(), 0.02);
  EXPECT_NE(r.err.find("  verdict: error bound = predicted error + "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("held-out reference frames it calls enough at 1%: "), std::string::npos)
      << r.err;
  EXPECT_EQ(one.frames, two.frames) << "the picks come from the main clip";
  EXPECT_EQ(one.drivenShapes, two.drivenShapes);
  EXPECT_EQ(one.poseModel.frameCount(), 61);
  EXPECT_EQ(two.poseModel.frameCount(), 61 + 24);
  ASSERT_EQ(two.extraClips.size(), 1u);
  EXPECT_EQ(two.extraClips[0].drivenSource, sample("test.driven.pc2"));
  EXPECT_EQ(two.extraClips[0].frames.size(), 24u);
  r = runCli(dir, {"info", dir.file("two.dsdb")});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("reference clip 2 (pose model only): driver " + sample("test.driver.pc2")),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("% of the cloth's rest diagonal: a lower coverage tolerance flags every "
                       "frame)"),
            std::string::npos)
      << r.out;
}

TEST(DbBuild, ModelPerClipMixesEachClipsModelAndSaysSo) {
  TempDir dir;
  const std::string test = sample("test.driver.pc2"), cloth = sample("test.driven.pc2");
  const std::vector<std::string> three = {"--also", test, cloth + ":1-24",
                                          "--also", test, cloth + ":25-48"};
  std::vector<std::string> args = three;
  args.insert(args.end(), {"--model-per-clip", "2", "-o", dir.file("mixed.dsdb"), "--model-json",
                           dir.file("mixed.json")});
  CliRun r = build(dir, args);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("per-clip models, each clip left out in turn: mean error "),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("mixed in at weight 2"), std::string::npos) << r.err;
  const nlohmann::json fit = nlohmann::json::parse(slurp(dir.file("mixed.json")));
  EXPECT_EQ(fit["per_clip_models"]["weight"].get<double>(), 2.0);
  ASSERT_EQ(fit["per_clip_models"]["tried"].size(), 2u) << "none, and the weight given";
  EXPECT_EQ(loadDatabase(dir.file("mixed.dsdb")).poseModel.clipSizes,
            (std::vector<int>{61, 24, 24}));
  r = runCli(dir, {"info", dir.file("mixed.dsdb")});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("per-clip models of 3 clips mixed in (weight of the model over every "
                       "clip 2)"),
            std::string::npos)
      << r.out;
  args = three;
  args.insert(args.end(), {"--model-per-clip", "off", "-o", dir.file("off.dsdb")});
  r = build(dir, args);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("per-clip models"), std::string::npos) << r.err;
  EXPECT_EQ(loadDatabase(dir.file("off.dsdb")).poseModel.clipMixtureWeight, 0.0);
  r = build(dir, {"--model-per-clip", "1", "-o", dir.file("one.dsdb")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("per-clip models: one reference clip, nothing to mix"), std::string::npos)
      << r.err;
}

TEST(DbBuild, SuggestListsFramesDeterministicallyWithoutWritingADatabase) {
  TempDir dir;
  const std::vector<std::string> words = {"--suggest",      "4",
                                          "--candidate",    sample("test.driver.pc2"),
                                          "--shot",         sample("test.driver.pc2") + ":25-48",
                                          "--suggest-json", dir.file("suggest.json"),
                                          "--quiet"};
  const CliRun r = build(dir, words);
  ASSERT_EQ(r.code, 0) << r.err;
  const std::vector<int> frames = suggestedFrames(r.out);
  ASSERT_EQ(frames.size(), 4u) << r.out;
  EXPECT_EQ(filesIn(dir.path()), std::vector<std::string>{dir.file("suggest.json")})
      << "no -o: nothing but the suggestions is written";
  const nlohmann::json json = nlohmann::json::parse(slurp(dir.file("suggest.json")));
  ASSERT_EQ(json.at("suggestions").size(), 4u);
  double before = json["suggestions"][0]["error_before"].get<double>();
  for (std::size_t i = 0; i < 4; ++i) {
    const nlohmann::json& s = json["suggestions"][i];
    EXPECT_EQ(s["frame"].get<int>(), frames[i]);
    EXPECT_EQ(s["error_before"].get<double>(), before);
    EXPECT_LT(s["error_after"].get<double>(), before) << "each suggestion lowers the error";
    before = s["error_after"].get<double>();
  }
  const CliRun again = build(dir, words);
  EXPECT_EQ(again.out, r.out) << "the same suggestions every run";

  // With -o the database is written as well; more frames asked than the candidate clip has:
  // each of its frames once.
  const CliRun both =
      build(dir, {"--suggest", "10", "--candidate", sample("test.driver.pc2") + ":1-3", "--shot",
                  sample("test.driver.pc2"), "-o", dir.file("db.dsdb")});
  ASSERT_EQ(both.code, 0) << both.err;
  std::vector<int> all = suggestedFrames(both.out);
  std::sort(all.begin(), all.end());
  EXPECT_EQ(all, (std::vector<int>{1, 2, 3})) << both.out;
  EXPECT_NE(both.out.find("database: "), std::string::npos);
  EXPECT_NE(both.err.find("suggesting every one of the 3 candidate frames (asked for 10)"),
            std::string::npos)
      << both.err;
}

TEST(DbBuild, BadClipsAndSuggestionsAreRefusedWithTheirExitCodes) {
  TempDir dir;
  const std::string test = sample("test.driver.pc2"), cloth = sample("test.driven.pc2");
  const std::string db = dir.file("db.dsdb");
  // Usage (2).
  expectError(build(dir, {"--also", test, "-o", db}), 2, "'--also' needs 2 values");
  expectError(build(dir, {"--suggest", "0", "--candidate", test, "--shot", test}), 2,
              "--suggest takes a whole number >= 1");
  expectError(build(dir, {"--suggest", "3", "--shot", test}), 2, "--candidate");
  expectError(build(dir, {"--suggest", "3", "--candidate", test}), 2, "--shot");
  expectError(build(dir, {"--candidate", test, "-o", db}), 2, "--candidate goes with --suggest");
  expectError(
      build(dir, {"--suggest", "3", "--candidate", test, "--shot", test, "--model", "none"}), 2,
      "drop --model none");
  expectError(build(dir, {"--also", test, cloth, "--model", "none", "-o", db}), 2, "--also");
  expectError(build(dir, {}), 2, "-o DB");
  expectError(build(dir, {"--verdict-level", "1", "-o", db}), 2, "--verdict-level");
  expectError(build(dir, {"--model", "none", "--model-json", dir.file("m.json"), "-o", db}), 2,
              "drop --model none");
  // Input (3): missing files, caches of another mesh, frames the cache lacks.
  expectError(build(dir, {"--also", dir.file("missing.pc2"), cloth, "-o", db}), 3, "missing.pc2");
  expectError(build(dir, {"--also", cloth, cloth, "-o", db}), 3,
              "reference clip 2: driver cache '" + cloth + "' has 2244 vertices");
  expectError(build(dir, {"--also", test, test + ":1-5", "-o", db}), 3,
              "reference clip 2: driven cache '" + test + "' has 2146 vertices");
  expectError(build(dir, {"--also", test, cloth + ":40-60", "-o", db}), 3, "has no frame 49");
  expectError(build(dir, {"--suggest", "3", "--candidate", dir.file("nope.pc2"), "--shot", test}),
              3, "nope.pc2");
  expectError(build(dir, {"--suggest", "3", "--candidate", test, "--shot", cloth}), 3,
              "shot 1: driver cache '" + cloth + "' has 2244 vertices");
  expectError(build(dir, {"--suggest", "3", "--candidate", test + ":100-120", "--shot", test}), 3,
              "candidate clip: cache '" + test + "' has no frame 100");
  EXPECT_TRUE(filesIn(dir.path()).empty()) << "nothing written by a failed build";
}

}  // namespace
}  // namespace drivenshape
