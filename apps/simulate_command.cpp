// SPDX-License-Identifier: Apache-2.0
// `drivenshape simulate` (issue 44): plans the windows of the frames a bake's verdict flags,
// runs each in Blender as a subprocess (no shell) through the add-on's simulate_window.py,
// keeps the windows a rerun finds complete, and splices them into the baked frames. The plan,
// the splice and the files are the library's (drivenshape/simulation.h).

#include "simulate_command.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/settings_table.h>
#include <drivenshape/simulation.h>

#include "atomic_file.h"
#include "stopwatch.h"

#include "cli_args.h"

extern char** environ;

namespace drivenshape::cli {
namespace {

namespace fs = std::filesystem;

/// Overrides where the runner is looked for: for tests and debugging a runner.
constexpr const char* kRunnerVariable = "DRIVENSHAPE_SIMULATE_RUNNER";
/// The runner in an installed tree, under the prefix (cmake/install.cmake installs the add-on's
/// module there).
constexpr const char* kInstalledRunner =
    "share/drivenshape/blender/drivenshape_blender/simulate_window.py";
#ifdef DS_SIMULATE_RUNNER_SOURCE
/// The runner in the source tree, for the build tree's drivenshape.
constexpr const char* kSourceRunner = DS_SIMULATE_RUNNER_SOURCE;
#else
constexpr const char* kSourceRunner = "";
#endif

ArgParser simulateParser() {
  ArgParser parser(
      "drivenshape simulate --blend SHOT.blend --object GARMENT --report BAKE.report.json "
      "--bake BAKE.####.exr -o OUT.####.exr",
      "Simulates the frames a bake's verdict flags with Blender's cloth solver and splices them "
      "into the bake: plans windows of the flagged frames (merged across short gaps, each "
      "started a warm-up earlier from the bake's cloth) and writes the plan as "
      "<OUT name>.simulation-plan.json; runs each window in `blender -b` (the garment's Cloth "
      "modifier in SHOT.blend, pulled towards the bake by --goal-strength); then writes every "
      "frame of the report to -o (simulated in the windows, cross-faded at their seams, the "
      "simulation's residual carried and faded after them, baked elsewhere) and "
      "<OUT name>.report.json with each frame's source. Windows go to <OUT name>.simulate-windows "
      "beside the output and stay there: a rerun simulates only what is missing (and a new --seam "
      "or --carry only splices again); remove the folder once the shot is final.");
  parser.option("--report", "PATH", "the bake's report (bake --report)", "", true)
      .option("-o", "OUT.####.exr", "output EXR sequence (####, %04d or $F4)", "", true)
      .option("--blend", "SHOT.blend", "the shot's scene with the garment's cloth setup")
      .option("--object", "GARMENT", "the garment object (its Cloth modifier simulates)")
      .option("--bake", "BAKE.####.exr", "the bake's EXR sequence (every frame of the report)")
      .settings(SettingScope::kSimulate)
      .option("--blender", "PATH", "the Blender executable (a name without / is looked up on PATH)",
              "blender on PATH")
      .flag("--plan-only", "write and print the plan, simulate nothing")
      .option("--window", "N",
              "job control (a farm's window task): simulate window N of the plan only (1 = the "
              "first), keeping it when a run before left it complete; no splice")
      .flag("--splice-only",
            "job control (a farm's splice task): simulate nothing, splice the windows that "
            "--window tasks left (every one must be complete) and write the report")
      .flag("--quiet", "no progress lines")
      .epilog(
          "`drivenshape farm slurm|openjd simulate` writes a job of these: a --window task per "
          "window, then a --splice-only task. Exit codes: 0 ok, 2 usage, 3 input (the report, "
          "the bake, Blender or the runner missing, a window whose simulation failed or, with "
          "--splice-only, is not there), 4 output, 7 stopped by SIGTERM or SIGINT (passed on to "
          "Blender; the windows finished before are kept).");
  return parser;
}

/// `<folder of -o>/<its sequence name><suffix>`.
std::string besideOutput(const std::string& pattern, const std::string& suffix) {
  return (fs::path(pattern).parent_path() / (sequenceStem(pattern) + suffix)).string();
}

bool isExecutableFile(const std::string& path) {
  struct stat info {};
  return ::stat(path.c_str(), &info) == 0 && S_ISREG(info.st_mode) &&
         ::access(path.c_str(), X_OK) == 0;
}

/// --blender (a path, or a name without '/' looked up on PATH as a shell would), else the first
/// `blender` on PATH.
std::string blenderPath(const ArgParser& parser) {
  const std::string given = parser.has("--blender") ? parser.get("--blender") : "blender";
  if (given.find('/') != std::string::npos) {
    if (!isExecutableFile(given)) {
      DS_THROW(kInput, "--blender '", given, "' is not an executable file");
    }
    return given;
  }
  const char* pathVariable = std::getenv("PATH");
  std::istringstream folders(pathVariable != nullptr ? pathVariable : "");
  for (std::string folder; std::getline(folders, folder, ':');) {
    const std::string candidate = (fs::path(folder.empty() ? "." : folder) / given).string();
    if (isExecutableFile(candidate)) {
      return candidate;
    }
  }
  DS_THROW(kInput, "no `", given, "` on PATH (", pathVariable != nullptr ? pathVariable : "unset",
           "); install Blender 3.4 or later, or name it with --blender PATH");
}

/// simulate_window.py: $DRIVENSHAPE_SIMULATE_RUNNER, else the installed one beside this
/// executable's prefix, else the source tree's.
std::string runnerPath() {
  if (const char* variable = std::getenv(kRunnerVariable); variable != nullptr && *variable) {
    requireRegularFile(variable, std::string("simulation runner ($") + kRunnerVariable + ")");
    return variable;
  }
  std::error_code error;
  const fs::path exe = fs::read_symlink("/proc/self/exe", error);
  const std::string installed =
      error ? std::string() : (exe.parent_path().parent_path() / kInstalledRunner).string();
  for (const std::string& candidate : {installed, std::string(kSourceRunner)}) {
    if (!candidate.empty() && fs::is_regular_file(candidate, error)) {
      return candidate;
    }
  }
  DS_THROW(kInput, "the simulation runner simulate_window.py is missing (looked for '", installed,
           "'", *kSourceRunner != '\0' ? std::string(" and '") + kSourceRunner + "'" : "",
           "); install drivenshape with its Blender module, or set ", kRunnerVariable);
}

/// The Blender being waited for, and the stop signal that came meanwhile (0: none).
volatile std::sig_atomic_t gChild = 0;
volatile std::sig_atomic_t gStopSignal = 0;

/// SIGTERM (a farm's cancel) and SIGINT (Ctrl-C) while a window simulates: passed on to Blender,
/// so that no simulation goes on writing after the command has gone.
extern "C" void forwardStopSignal(int signal) {
  gStopSignal = signal;
  if (gChild > 0) {
    ::kill(static_cast<pid_t>(gChild), signal);
  }
}

/// Runs `argv` without a shell, its stdout and stderr into the file `log`; returns its exit
/// status (128 + the signal that ended it). A SIGTERM or SIGINT meanwhile goes to the child too,
/// and once it has ended: Error(kInterrupted).
int runLogged(const std::vector<std::string>& argv, const std::string& log) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  std::vector<char*> words;
  for (const std::string& word : argv) {
    words.push_back(const_cast<char*>(word.c_str()));
  }
  words.push_back(nullptr);
  pid_t pid = 0;
  std::signal(SIGTERM, forwardStopSignal);
  std::signal(SIGINT, forwardStopSignal);
  const int failed = posix_spawn(&pid, argv[0].c_str(), &actions, nullptr, words.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (failed != 0) {
    DS_THROW(kInput, "cannot run '", argv[0], "': ", std::strerror(failed));
  }
  gChild = pid;
  if (gStopSignal != 0) {  // a signal between the spawn and gChild: pass it on now
    ::kill(pid, gStopSignal);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) {
      DS_THROW(kInternal, "waiting for '", argv[0], "': ", std::strerror(errno));
    }
  }
  gChild = 0;
  std::signal(SIGTERM, SIG_DFL);  // outside a window a stop ends the command at once: every
  std::signal(SIGINT, SIG_DFL);   // file it writes is renamed into place whole
  if (gStopSignal != 0) {
    DS_THROW(kInterrupted,
             "stopped by a signal while Blender simulated a window (passed on to "
             "it); the windows finished before are kept: run the same command again to resume");
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/// The last line of text in the file at `path` that is not empty, or "".
std::string lastLine(const std::string& path) {
  std::istringstream text(readWholeFile(path, "log"));
  std::string line, last;
  while (std::getline(text, line)) {
    last = line.find_first_not_of(" \t\r") == std::string::npos ? last : line;
  }
  return last.size() > 300 ? last.substr(0, 300) + "..." : last;
}

/// What simulating the windows needs: the command's inputs and where the windows go.
struct WindowJob {
  std::string blender, runner, blend, object, bake, folder;
  double goalStrength = 0.0;
  int vertexCount = 0;
};

std::string windowPattern(const WindowJob& job, const SimulationWindow& window) {
  return job.folder + "/window_" + std::to_string(window.from) + "/w.####.exr";
}

/// The runner's command line for `window` (docs/commands.md, "drivenshape simulate").
std::vector<std::string> runnerArgs(const WindowJob& job, const SimulationWindow& window) {
  return {job.blender,
          "-b",
          job.blend,
          "--python-exit-code",
          "1",
          "--python",
          job.runner,
          "--",
          "--object",
          job.object,
          "--bake",
          job.bake,
          "--first",
          std::to_string(window.warmupFrom),
          "--last",
          std::to_string(window.to),
          "--goal-strength",
          formatSettingValue(job.goalStrength),
          "-o",
          windowPattern(job, window)};
}

/// The stamp of a window's folder: the runner's command line but Blender's path (another
/// Blender may keep the window), and the bake's frames it read.
std::string windowStamp(const WindowJob& job, const SimulationWindow& window) {
  const std::vector<std::string> args = runnerArgs(job, window);
  std::string stamp;
  for (std::size_t i = 1; i < args.size(); ++i) {
    stamp += args[i] + "\n";
  }
  return stamp + "bake frames " + bakeFramesStamp(job.bake, window.warmupFrom, window.to) + "\n";
}

fs::path windowFolder(const WindowJob& job, const SimulationWindow& window) {
  return fs::path(windowPattern(job, window)).parent_path();
}

/// Whether a run before left `window` complete, with the stamp `stamp` (windowStamp()).
bool windowKept(const WindowJob& job, const SimulationWindow& window, const std::string& stamp) {
  const std::string file = (windowFolder(job, window) / "window.args").string();
  std::error_code error;
  return fs::is_regular_file(file, error) && readWholeFile(file, "window stamp") == stamp &&
         simulatedWindowProblem(window, windowPattern(job, window), job.vertexCount).empty();
}

/// Simulates `window` in Blender into a fresh folder and records `stamp` (windowStamp(), taken
/// before the run: the bake it started from); Error(kInput) naming the window and Blender's log
/// when Blender fails or leaves a frame missing.
void simulateWindow(const WindowJob& job, const SimulationWindow& window,
                    const std::string& stamp) {
  const fs::path folder = windowFolder(job, window);
  std::error_code error;
  fs::remove_all(folder, error);
  createOutputFolders((folder / "w.exr").string());
  const std::string log = (folder / "blender.log").string();
  const std::string range = "window " + std::to_string(window.from) + "-" +
                            std::to_string(window.to) + " (simulated from " +
                            std::to_string(window.warmupFrom) + ")";
  const int status = runLogged(runnerArgs(job, window), log);
  if (status != 0) {
    DS_THROW(kInput, range, ": Blender exited with status ", status, " (", lastLine(log),
             "); its log: ", log);
  }
  const std::string problem =
      simulatedWindowProblem(window, windowPattern(job, window), job.vertexCount);
  if (!problem.empty()) {
    DS_THROW(kInput, range, ": the runner finished but ", problem, "; its log: ", log);
  }
  writeFileAtomically((folder / "window.args").string(), stamp);
}

void printPlan(const SimulationPlan& plan, const std::string& path) {
  std::cout << "plan:    " << plan.windows.size() << " windows, " << plan.simulatedFrames()
            << " frames simulated of " << plan.last - plan.first + 1 << " (" << plan.first << "-"
            << plan.last << ")\n";
  for (const SimulationWindow& window : plan.windows) {
    std::cout << "  frames " << window.warmupFrom << "-" << window.to << ", handing back "
              << window.from << "-" << window.to << "\n";
  }
  std::cout << "written: " << absolute(path) << "\n";
}

/// The options that --plan-only leaves out, required otherwise.
void requireSimulationInputs(const ArgParser& parser) {
  for (const char* option : {"--blend", "--object", "--bake"}) {
    if (!parser.has(option)) {
      DS_THROW(kUsage, "missing required option ", option,
               " for `drivenshape simulate` (only --plan-only goes without it); see --help");
    }
  }
  if (!hasFramePattern(parser.get("--bake"))) {
    DS_THROW(kUsage, "--bake '", parser.get("--bake"), "' has no frame token");
  }
}

/// Refuses outputs that name one file or an input, before anything is written.
void checkSimulatePaths(const ArgParser& parser, const SimulationPlan& plan) {
  const std::string output = parser.get("-o");
  const std::vector<NamedPath> outputs = {
      {"-o", output, true},
      {"the plan", besideOutput(output, ".simulation-plan.json"), false},
      {"the simulate report", besideOutput(output, ".report.json"), false}};
  std::vector<NamedPath> inputs = givenPaths(parser, {"--report", "--blend"});
  const std::vector<NamedPath> bake = givenPaths(parser, {"--bake"}, true);
  inputs.insert(inputs.end(), bake.begin(), bake.end());
  std::vector<int> frames;
  for (int f = plan.first; f <= plan.last; ++f) {
    frames.push_back(f);
  }
  checkDistinctPaths(outputs, frames, inputs);
}

/// What the windows need, from the command line; `blender` false for --splice-only, which
/// starts none (a window's stamp leaves Blender's path out).
WindowJob windowJobOf(const ArgParser& parser, const SimulationPlan& plan, bool blender) {
  const ExrPointCacheInfo bake = checkSimulationBake(plan, parser.get("--bake"));
  WindowJob job{blender ? blenderPath(parser) : std::string(),
                runnerPath(),
                absolute(parser.get("--blend")),
                parser.get("--object"),
                absolute(parser.get("--bake")),
                absolute(besideOutput(parser.get("-o"), ".simulate-windows")),
                plan.settings.goalStrength,
                bake.vertexCount};
  requireRegularFile(job.blend, "scene");
  return job;
}

/// Window w (0-based) of the plan: kept when a run before left it complete, else simulated.
void runWindow(const WindowJob& job, const SimulationPlan& plan, std::size_t w, bool quiet) {
  const SimulationWindow& window = plan.windows[w];
  const std::string stamp = windowStamp(job, window);
  const bool kept = windowKept(job, window, stamp);
  if (!quiet) {
    std::cerr << "window " << w + 1 << "/" << plan.windows.size() << ": frames "
              << window.warmupFrom << "-" << window.to
              << (kept ? " kept from a run before\n" : " simulating in Blender\n");
  }
  if (!kept) {
    simulateWindow(job, window, stamp);
  }
}

/// --splice-only: every window must be complete from the same command line; Error(kInput)
/// naming the first that is not and the task that makes it.
void requireEveryWindow(const WindowJob& job, const SimulationPlan& plan) {
  for (std::size_t w = 0; w < plan.windows.size(); ++w) {
    const SimulationWindow& window = plan.windows[w];
    if (!windowKept(job, window, windowStamp(job, window))) {
      const std::string problem =
          simulatedWindowProblem(window, windowPattern(job, window), job.vertexCount);
      DS_THROW(kInput, "--splice-only: window ", w + 1, " of ", plan.windows.size(), " (frames ",
               window.warmupFrom, "-", window.to, ") is not complete in '",
               windowFolder(job, window).string(), "' (",
               problem.empty() ? "simulated with other inputs or settings" : problem,
               "); run its task first: the same command with --window ", w + 1);
    }
  }
}

/// Splices the windows into -o; returns the splice. The windows stay: a rerun (a lost output, a
/// new --seam or --carry) splices again without simulating.
SplicedShot splice(const ArgParser& parser, const SimulationPlan& plan, const WindowJob& job,
                   bool quiet) {
  std::vector<std::string> patterns;
  for (const SimulationWindow& window : plan.windows) {
    patterns.push_back(windowPattern(job, window));
  }
  if (!quiet) {
    std::cerr << "splicing " << plan.last - plan.first + 1 << " frames\n";
  }
  return spliceSimulationFiles(plan, parser.get("--bake"), patterns, parser.get("-o"));
}

/// The mode the job-control options ask for; Error(kUsage) for two at once.
enum class SimulateMode { kAll, kPlanOnly, kWindow, kSpliceOnly };
SimulateMode simulateMode(const ArgParser& parser) {
  std::vector<std::string> given;
  for (const char* option : {"--plan-only", "--window", "--splice-only"}) {
    if (parser.has(option)) {
      given.emplace_back(option);
    }
  }
  if (given.size() > 1) {
    DS_THROW(kUsage, given[0], " and ", given[1], " exclude each other");
  }
  return parser.has("--plan-only")     ? SimulateMode::kPlanOnly
         : parser.has("--window")      ? SimulateMode::kWindow
         : parser.has("--splice-only") ? SimulateMode::kSpliceOnly
                                       : SimulateMode::kAll;
}

/// --window N as a 0-based index of the plan's windows; Error(kUsage) naming it when the plan
/// has no window N.
std::size_t windowIndex(const ArgParser& parser, const SimulationPlan& plan) {
  const int n = parser.getInt("--window", 1);
  if (static_cast<std::size_t>(n) > plan.windows.size()) {
    DS_THROW(kUsage, "--window ", n, ": the plan of ", plan.report, " has ", plan.windows.size(),
             plan.windows.size() == 1 ? " window" : " windows",
             plan.windows.empty() ? "" : " (1-" + std::to_string(plan.windows.size()) + ")");
  }
  return static_cast<std::size_t>(n - 1);
}

}  // namespace

int runSimulate(const std::vector<std::string>& args) {
  ArgParser parser = simulateParser();
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const auto start = std::chrono::steady_clock::now();
  SimulationOptions settings;
  readSettings(parser, settings);
  const std::string output = parser.get("-o");
  if (!hasFramePattern(output)) {
    DS_THROW(kUsage, "-o '", output, "' has no frame token; use e.g. final/cloth.####.exr");
  }
  const SimulateMode mode = simulateMode(parser);
  const bool quiet = parser.has("--quiet");
  if (mode != SimulateMode::kPlanOnly) {
    requireSimulationInputs(parser);
  }
  const SimulationPlan plan =
      planSimulation(readBakeReportCoverage(parser.get("--report")), settings);
  const std::size_t window = mode == SimulateMode::kWindow ? windowIndex(parser, plan) : 0;
  checkSimulatePaths(parser, plan);
  const std::string planPath = besideOutput(output, ".simulation-plan.json");
  createOutputFoldersFor({planPath}, quiet);
  writeFileAtomically(planPath, simulationPlanJson(plan));
  printPlan(plan, planPath);
  if (mode == SimulateMode::kPlanOnly) {
    return 0;
  }
  const WindowJob job = windowJobOf(parser, plan, mode != SimulateMode::kSpliceOnly);
  if (mode == SimulateMode::kWindow) {
    runWindow(job, plan, window, quiet);
    std::cout << "window:  " << window + 1 << "/" << plan.windows.size() << " in "
              << windowFolder(job, plan.windows[window]).string() << "\n";
    return 0;
  }
  for (std::size_t w = 0; mode == SimulateMode::kAll && w < plan.windows.size(); ++w) {
    runWindow(job, plan, w, quiet);
  }
  if (mode == SimulateMode::kSpliceOnly) {
    requireEveryWindow(job, plan);
  }
  const SplicedShot shot = splice(parser, plan, job, quiet);
  const std::string reportPath = besideOutput(output, ".report.json");
  writeFileAtomically(reportPath, simulateReportJson(plan, shot.sources, secondsSince(start)));
  std::cout << "outputs: " << absolute(output) << " (frames " << plan.first << "-" << plan.last
            << ")\nreport:  " << absolute(reportPath) << "\n";
  return 0;
}

}  // namespace drivenshape::cli
