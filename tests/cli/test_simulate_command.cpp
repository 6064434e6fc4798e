// SPDX-License-Identifier: Apache-2.0
// `drivenshape simulate` end to end with a stand-in Blender (stand_in_blender.cpp): the plan
// beside the output, the runner's command line per window, every frame written with its source,
// the output equal to the library's splice of the same frames computed here, a failed window
// (exit 3 naming it, no output frame, the windows before it kept for the rerun), --plan-only and
// the missing inputs. The stand-in tests the command's plumbing only; the real runner in
// Blender is tests/blender's.

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/types.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <drivenshape/frames.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/simulation.h>

#include "cli_test_util.h"
#include "stand_in_blender.h"

namespace drivenshape::testing {
namespace {

constexpr int kVertices = 5;
constexpr int kFirst = 1, kLast = 30;
constexpr std::uint64_t kTopology = 0xabcdef12345ull;

float bakedValue(int frame, int vertex, int axis) {
  return axis == 0   ? static_cast<float>(vertex) + 0.1f * static_cast<float>(frame)
         : axis == 1 ? std::sin(0.3f * static_cast<float>(frame) + static_cast<float>(vertex))
                     : 0.01f * static_cast<float>(vertex * frame);
}

/// A bake of frames 1-30 (out/x.####.exr), its report flagging 8-10 and 24, a scene file and a
/// runner file (the stand-in only checks that they exist).
class SimulateCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    std::filesystem::create_directories(mDir.file("out"));
    for (int f = kFirst; f <= kLast; ++f) {
      std::vector<float> xyz;
      for (int v = 0; v < kVertices; ++v) {
        for (int a = 0; a < 3; ++a) {
          xyz.push_back(bakedValue(f, v, a));
        }
      }
      ExrWriteOptions options;
      options.frame = f;
      options.topologyHash = kTopology;
      options.framesPerSecond = 25.0;
      writePointCacheExr(expandFramePattern(bake(), f), kVertices, xyz.data(), nullptr, options);
      mBaked.insert(mBaked.end(), xyz.begin(), xyz.end());
    }
    nlohmann::json frames = nlohmann::json::array();
    for (int f = kFirst; f <= kLast; ++f) {
      const bool flagged = (f >= 8 && f <= 10) || f == 24;
      frames.push_back({{"frame", f},
                        {"predicted_error", flagged ? 0.05 : 0.01},
                        {"coverage", {{"flagged", flagged}}}});
    }
    writeText(mDir.file("out/x.report.json"),
              nlohmann::json{{"coverage", {{"tolerance", 0.02}}}, {"frames", frames}}.dump());
    writeText(mDir.file("shot.blend"), "a scene");
    writeText(mDir.file("simulate_window.py"), "# the runner");
    ::setenv("DRIVENSHAPE_SIMULATE_RUNNER", mDir.file("simulate_window.py").c_str(), 1);
    ::setenv("STAND_IN_LOG", mDir.file("runs.log").c_str(), 1);
    ::unsetenv("STAND_IN_FAIL_AT");
  }
  void TearDown() override {
    ::unsetenv("DRIVENSHAPE_SIMULATE_RUNNER");
    ::unsetenv("STAND_IN_LOG");
    ::unsetenv("STAND_IN_FAIL_AT");
    ::unsetenv("STAND_IN_HANG");
  }

  static void writeText(const std::string& path, const std::string& text) {
    std::FILE* file = std::fopen(path.c_str(), "wb");
    ASSERT_NE(file, nullptr) << path;
    std::fwrite(text.data(), 1, text.size(), file);
    std::fclose(file);
  }
  std::string bake() const { return mDir.file("out/x.####.exr"); }
  std::string output() const { return mDir.file("final/x.####.exr"); }
  /// The command line of a simulation of the shot with the stand-in Blender, then `extra`.
  std::vector<std::string> simulateArgs(std::vector<std::string> extra = {}) const {
    std::vector<std::string> args = {"simulate",
                                     "--blend",
                                     mDir.file("shot.blend"),
                                     "--object",
                                     "pants",
                                     "--report",
                                     mDir.file("out/x.report.json"),
                                     "--bake",
                                     bake(),
                                     "-o",
                                     output(),
                                     "--blender",
                                     DS_STAND_IN_BLENDER,
                                     "--warmup",
                                     "4",
                                     "--merge-gap",
                                     "2",
                                     "--seam",
                                     "2",
                                     "--carry",
                                     "3"};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }
  CliRun simulate(std::vector<std::string> extra = {}) { return runCli(mDir, simulateArgs(extra)); }

  TempDir mDir;
  std::vector<float> mBaked;  ///< frames 1-30
};

TEST_F(SimulateCommand, WritesEveryFrameAsTheLibrarySplicesIt) {
  const CliRun r = simulate({"--goal-strength", "0.5"});
  ASSERT_EQ(r.code, 0) << r.err;
  // Windows: 8-10 warmed up from 4; 24 from 20 (13 frames after 10: no merge).
  EXPECT_EQ(slurp(mDir.file("runs.log")),
            "--object pants --bake " + bake() + " --first 4 --last 10 --goal-strength 0.5 -o " +
                mDir.file("final/x.simulate-windows/window_8/w.####.exr") +
                " \n--object pants --bake " + bake() +
                " --first 20 --last 24 --goal-strength 0.5 -o " +
                mDir.file("final/x.simulate-windows/window_24/w.####.exr") + " \n");
  const SimulationPlan plan = readSimulationPlan(mDir.file("final/x.simulation-plan.json"));
  ASSERT_EQ(plan.windows.size(), 2u);
  EXPECT_EQ(plan.settings.goalStrength, 0.5);
  // The expected output: the library's splice of the bake and the stand-in's windows.
  std::vector<std::vector<float>> simulated;
  for (const SimulationWindow& window : plan.windows) {
    simulated.emplace_back();
    for (int f = window.warmupFrom; f <= window.to; ++f) {
      for (int i = 0; i < 3 * kVertices; ++i) {
        simulated.back().push_back(mBaked[(f - kFirst) * 3 * kVertices + i] +
                                   simulatedOffset(f, i / 3, i % 3));
      }
    }
  }
  const SplicedShot expected = spliceSimulation(plan, kVertices, mBaked, simulated);
  const nlohmann::json report = nlohmann::json::parse(slurp(mDir.file("final/x.report.json")));
  EXPECT_EQ(report.at("format"), "drivenshape-simulate-report");
  ASSERT_EQ(report.at("frames").size(), 30u);
  std::string sources;
  std::vector<float> xyz;
  for (int f = kFirst; f <= kLast; ++f) {
    const ExrPointCacheInfo info = readPointCacheExr(expandFramePattern(output(), f), xyz);
    const std::vector<float> want(expected.positions.begin() + (f - kFirst) * 3 * kVertices,
                                  expected.positions.begin() + (f - kFirst + 1) * 3 * kVertices);
    EXPECT_EQ(xyz, want) << "frame " << f;
    const std::string source = frameSourceName(expected.sources[f - kFirst]);
    EXPECT_EQ(info.stringAttributes.at("dsSource"), source) << "frame " << f;
    EXPECT_EQ(report.at("frames")[f - kFirst].at("source"), source) << "frame " << f;
    EXPECT_EQ(info.topologyHash, kTopology);
    EXPECT_EQ(info.framesPerSecond, 25.0);
    sources += source == "baked" ? 'B' : source == "simulated" ? 'S' : 'L';
  }
  // Seam 6-7, window 8-10, carry 11-13; seam 22-23, window 24, carry 25-27.
  EXPECT_EQ(sources, "BBBBBLLSSSLLLBBBBBBBBLLSLLLBBB");
}

// The windows stay beside the output: a rerun simulates nothing and writes the same frames, and
// a new --carry (not on a window's command line) splices the same windows again.
TEST_F(SimulateCommand, ARerunAfterASpliceSimulatesNothing) {
  ASSERT_EQ(simulate().code, 0);
  std::vector<std::string> first;
  for (int f = kFirst; f <= kLast; ++f) {
    first.push_back(slurp(expandFramePattern(output(), f)));
  }
  std::filesystem::remove(mDir.file("runs.log"));
  const CliRun rerun = simulate();
  ASSERT_EQ(rerun.code, 0) << rerun.err;
  EXPECT_NE(rerun.err.find("window 2/2: frames 20-24 kept from a run before"), std::string::npos)
      << rerun.err;
  EXPECT_FALSE(std::filesystem::exists(mDir.file("runs.log")));
  for (int f = kFirst; f <= kLast; ++f) {
    EXPECT_EQ(slurp(expandFramePattern(output(), f)), first[f - kFirst]) << "frame " << f;
  }
  const CliRun carried = simulate({"--carry", "1"});
  ASSERT_EQ(carried.code, 0) << carried.err;
  EXPECT_FALSE(std::filesystem::exists(mDir.file("runs.log")));
  EXPECT_NE(slurp(expandFramePattern(output(), 12)), first[12 - kFirst]);  // carried before
}

// A window is kept only while the bake frames it simulated from are the same bytes: a new bake
// under the same name simulates the windows it changed again.
TEST_F(SimulateCommand, ANewBakeSimulatesTheWindowsItChangesAgain) {
  ASSERT_EQ(simulate().code, 0);
  std::filesystem::remove(mDir.file("runs.log"));
  std::vector<float> xyz(mBaked.begin() + (22 - kFirst) * 3 * kVertices,
                         mBaked.begin() + (23 - kFirst) * 3 * kVertices);
  xyz[0] += 0.5f;
  ExrWriteOptions options;
  options.frame = 22;
  options.topologyHash = kTopology;
  options.framesPerSecond = 25.0;
  writePointCacheExr(expandFramePattern(bake(), 22), kVertices, xyz.data(), nullptr, options);
  const CliRun rerun = simulate();
  ASSERT_EQ(rerun.code, 0) << rerun.err;
  EXPECT_NE(rerun.err.find("window 1/2: frames 4-10 kept from a run before"), std::string::npos)
      << rerun.err;
  EXPECT_NE(rerun.err.find("window 2/2: frames 20-24 simulating in Blender"), std::string::npos)
      << rerun.err;
  EXPECT_EQ(slurp(mDir.file("runs.log")).find("--first 4 "), std::string::npos);
  EXPECT_NE(slurp(mDir.file("runs.log")).find("--first 20 --last 24"), std::string::npos);
}

TEST_F(SimulateCommand, AFailedWindowWritesNoFrameAndARerunKeepsTheOthers) {
  ::setenv("STAND_IN_FAIL_AT", "22", 1);
  const CliRun failed = simulate();
  expectError(failed, 3, "window 24-24 (simulated from 20): Blender exited with status 1");
  EXPECT_NE(failed.err.find("the cloth exploded at frame 22"), std::string::npos) << failed.err;
  for (int f = kFirst; f <= kLast; ++f) {
    EXPECT_FALSE(std::filesystem::exists(expandFramePattern(output(), f))) << f;
  }
  EXPECT_TRUE(std::filesystem::exists(mDir.file("final/x.simulation-plan.json")));
  ::unsetenv("STAND_IN_FAIL_AT");
  std::filesystem::remove(mDir.file("runs.log"));
  const CliRun rerun = simulate();
  ASSERT_EQ(rerun.code, 0) << rerun.err;
  EXPECT_NE(rerun.err.find("window 1/2: frames 4-10 kept from a run before"), std::string::npos)
      << rerun.err;
  // Only the failed window ran again.
  EXPECT_NE(slurp(mDir.file("runs.log")).find("--first 20 --last 24"), std::string::npos);
  EXPECT_EQ(slurp(mDir.file("runs.log")).find("--first 4 "), std::string::npos);
  EXPECT_TRUE(std::filesystem::exists(expandFramePattern(output(), kLast)));
}

// A farm cancels a task with SIGTERM: the command passes it on to the Blender it waits for, so
// that no simulation goes on writing after it, and exits 7 with no output frame.
TEST_F(SimulateCommand, AStopReachesBlenderAndWritesNoFrame) {
  ::setenv("STAND_IN_HANG", mDir.file("blender.pid").c_str(), 1);
  const CliRun stopped = runCliStopped(mDir, simulateArgs(), 2.0);
  ::unsetenv("STAND_IN_HANG");
  expectError(stopped, 7, "stopped by a signal while Blender simulated a window");
  const pid_t blender = static_cast<pid_t>(std::stol(slurp(mDir.file("blender.pid"))));
  EXPECT_EQ(::kill(blender, 0), -1) << "the stand-in Blender " << blender << " still runs";
  EXPECT_EQ(errno, ESRCH);
  for (int f = kFirst; f <= kLast; ++f) {
    EXPECT_FALSE(std::filesystem::exists(expandFramePattern(output(), f))) << f;
  }
}

TEST_F(SimulateCommand, PlanOnlyWritesThePlanAlone) {
  const CliRun r = runCli(mDir, {"simulate", "--report", mDir.file("out/x.report.json"), "-o",
                                 output(), "--plan-only", "--merge-gap", "20"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("frames 1-24, handing back 8-24"), std::string::npos) << r.out;
  EXPECT_EQ(filesIn(mDir.file("final")),
            std::vector<std::string>{mDir.file("final/x.simulation-plan.json")});
  EXPECT_FALSE(std::filesystem::exists(mDir.file("runs.log")));
}

TEST_F(SimulateCommand, NamesWhatIsMissing) {
  expectError(simulate({"--blender", mDir.file("no-blender")}), 3, "--blender");
  std::filesystem::remove(expandFramePattern(bake(), 17));
  expectError(simulate(), 3, "has no frame 17");
  const CliRun noBlend =
      runCli(mDir, {"simulate", "--report", mDir.file("out/x.report.json"), "-o", output()});
  expectError(noBlend, 2, "--blend");
  expectError(simulate({"--seam", "-1"}), 2, "--seam");
  EXPECT_FALSE(std::filesystem::exists(expandFramePattern(output(), kFirst)));
}

TEST_F(SimulateCommand, FindsBlenderOnThePath) {
  const char* saved = std::getenv("PATH");
  const std::string path = saved != nullptr ? saved : "";
  ::setenv("PATH", mDir.file("out").c_str(), 1);
  const CliRun r =
      runCli(mDir, {"simulate", "--blend", mDir.file("shot.blend"), "--object", "p", "--report",
                    mDir.file("out/x.report.json"), "--bake", bake(), "-o", output()});
  ::setenv("PATH", path.c_str(), 1);
  expectError(r, 3, "no `blender` on PATH");
}

}  // namespace
}  // namespace drivenshape::testing
