// SPDX-License-Identifier: Apache-2.0
// `drivenshape farm slurm|openjd`: the options, the FarmJob they make, and the files the
// library's job model (src/shot/farm_job.h) writes.
#include "farm_command.h"

#include <filesystem>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include <drivenshape/coverage_check.h>
#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/simulation.h>

#include "atomic_file.h"
#include "farm_job.h"

#include "json_text.h"

#include "cli_args.h"
#include "commands.h"

namespace drivenshape::cli {
namespace {

namespace fs = std::filesystem;

const char* const kFarmExitCodes =
    "Each task runs `drivenshape bake ... --chunk-size N --chunk-index I --skip-existing`, so a "
    "retried task keeps the frames it finished and bakes the rest. Task exit codes are the "
    "bake's: 0 ok, 2 usage, 3 input, 4 output, 5 OpenCL device, 6 numerical, 7 interrupted "
    "(SIGTERM/SIGINT; rerun to resume). The farm command itself exits 2 for usage errors, 3 "
    "when an input is missing, 4 when the job file or log folder cannot be written or sbatch "
    "fails.";

void addJobOptions(ArgParser& parser) {
  parser.option("--db", "DB", "database from `drivenshape db build`", "", true)
      .option("--driver", "CACHE", "shot driver cache (.pc2 or name.####.exr)", "", true)
      .option("--frames", "RANGE", "frames of the shot: 1001-1100, 1001-1100x2, 1001,1005", "",
              true)
      .option("-o", "OUT.####.exr", "output EXR sequence (####, %04d or $F4)", "", true)
      .option("--chunk-size", "N",
              "frames per task; task I bakes frames [I*N, (I+1)*N) of --frames", "", true)
      .option("-O", "JOBFILE", "job file to write", "", true)
      .option("--job-name", "NAME", "job name", "ds_<output name>")
      .option("--time", "HH:MM:SS", "time limit per task (also MM or D-HH:MM:SS)")
      .option("--cpus", "N", "CPU cores per task (the bake uses as many threads)")
      .option("--mem", "MB", "memory per task in MiB")
      .option("--extra-args", "\"...\"",
              "more bake options for every task, e.g. \"--batch 16 --no-audit\"")
      .option("--binary", "PATH", "drivenshape executable the tasks run", "this executable")
      .flag("--no-check", "do not check from this machine that the inputs exist");
}

/// --binary made absolute, else this executable.
std::string drivenshapeBinary(const ArgParser& parser) {
  if (parser.has("--binary")) {
    return absolute(parser.get("--binary"));
  }
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) {
    DS_THROW(kInternal, "cannot find this executable through /proc/self/exe (", ec.message(),
             "); pass --binary /path/to/drivenshape");
  }
  return self.string();
}

/// Refuses --extra-args (`text`) that every task's bake would refuse: a task's whole command
/// line, the farm's options and these words, goes through the bake's own parser and value checks
/// (checkBakeArguments), so an unknown option, a missing value or a value out of range is a usage
/// error here, naming --extra-args and the word, rather than a failed task on the farm.
void checkExtraArgs(const FarmJob& job, const std::string& text) {
  std::vector<std::string> words = chunkBakeCommand(job, "0");
  words.erase(words.begin(), words.begin() + 2);  // the executable and `bake`
  try {
    checkBakeArguments(words);
  } catch (const Error& error) {
    if (error.code() != ErrorCode::kUsage) {
      throw;
    }
    DS_THROW(kUsage, culprit("--extra-args", text),
             ": every task's bake would refuse it: ", error.what());
  }
}

/// The job of the options, each value checked in the order the options are listed.
FarmJob jobFrom(const ArgParser& parser) {
  FarmJob job;
  job.binary = drivenshapeBinary(parser);
  job.database = absolute(parser.get("--db"));
  job.driver = absolute(parser.get("--driver"));
  job.outputPattern = absolute(parser.get("-o"));
  job.outputFolder = fs::path(job.outputPattern).parent_path().string();
  job.frames = parser.get("--frames");
  const std::vector<int> frames = parseFrameRange(job.frames);
  job.chunkSize = parser.getInt("--chunk-size", 1);
  planFarmChunks(job, frames);
  job.name =
      parser.has("--job-name") ? parser.get("--job-name") : defaultFarmJobName(job.outputPattern);
  checkFarmJob(job, parser.get("-o"), frames.front());
  if (parser.has("--time")) {
    job.timeLimit = parser.get("--time");
    parseTimeLimit(job.timeLimit);
  }
  job.cpus = parser.has("--cpus") ? parser.getInt("--cpus", 1) : 0;
  job.memoryMb = parser.has("--mem") ? parser.getInt("--mem", 1) : 0;
  if (parser.has("--extra-args")) {
    setFarmExtraArgs(job, parser.get("--extra-args"));
    checkExtraArgs(job, parser.get("--extra-args"));
  }
  if (!parser.has("--no-check")) {
    checkFarmInputs(job, frames);
  }
  return job;
}

/// Refuses job files (`outputs`: -O, the OpenJD parameters file) that would overwrite an input
/// of the job: the database, any frame of the driver, the executable the tasks run.
void checkFarmPaths(const ArgParser& parser, const FarmJob& job,
                    const std::vector<NamedPath>& outputs) {
  std::vector<NamedPath> inputs = givenPaths(parser, {"--db"});
  const std::vector<NamedPath> driver = givenPaths(parser, {"--driver"}, true);
  inputs.insert(inputs.end(), driver.begin(), driver.end());
  inputs.push_back({"--binary", job.binary, false});
  checkDistinctPaths(outputs, {}, inputs);
}

/// Creates `folder` (and parents); Error(kOutput) if it cannot be made or written.
void makeFolder(const std::string& folder, const char* what) {
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) {
    DS_THROW(kOutput, "cannot create the ", what, " folder '", folder, "': ", ec.message());
  }
  checkOutputFolderWritable((fs::path(folder) / "probe").string());
}

/// The bake wants its output folder to exist. Made here when this machine can (a shared file
/// system); otherwise a warning, since the workers may see paths this machine does not.
void createOutputFolder(const FarmJob& job) {
  std::error_code ec;
  fs::create_directories(job.outputFolder, ec);
  if (ec) {
    std::cerr << "warning: cannot create the output folder '" << job.outputFolder << "' from here ("
              << ec.message() << "); create it before the tasks run\n";
  }
}

/// The array job in `jobFile` and, after it, the job that runs its script's `stage` ("report",
/// "splice"; `what` in the output) with the dependency options `afterArray(array job id)`: with
/// `submit`, both submitted through sbatch; otherwise the two sbatch commands printed.
void submitOrPrintSlurm(
    bool submit, const std::string& jobFile, const std::string& stage, const std::string& what,
    const std::function<std::vector<std::string>(const std::string&)>& afterArray) {
  if (submit) {
    const std::string id = submitToSlurm(jobFile);
    std::cout << "submitted: job " << id << "\n";
    const std::string after = submitToSlurm(jobFile, afterArray(id), {stage});
    std::cout << "submitted: job " << after << " (" << what << ", after job " << id << ")\n";
    return;
  }
  std::string afterOptions;
  for (const std::string& option : afterArray("${id%%;*}")) {
    afterOptions +=
        " " + (option.find('$') == std::string::npos ? shellQuote(option) : "\"" + option + "\"");
  }
  std::cout << "submit with: id=$(sbatch --parsable " << shellQuote(jobFile) << ") &&\n"
            << "             sbatch" << afterOptions << " " << shellQuote(jobFile) << " " << stage
            << "\n";
}

int runFarmSlurm(const std::vector<std::string>& args) {
  ArgParser parser(
      "drivenshape farm slurm --db DB --driver CACHE --frames RANGE -o OUT.####.exr "
      "--chunk-size N -O job.sbatch",
      "Writes an sbatch array script for a shot: one array task per chunk of --chunk-size "
      "frames (array indices are chunk numbers, never frame numbers), a log per task, SIGTERM "
      "passed on to the bake, absolute paths throughout. --submit also runs sbatch and prints "
      "the job id.");
  addJobOptions(parser);
  parser.option("--partition", "P", "Slurm partition")
      .option("--log-dir", "DIR", "folder of the per-task logs (NAME_JOBID_CHUNK.log)",
              "OUT folder/logs")
      .option("--max-array-size", "N",
              "the cluster's MaxArraySize, when more than 1001 chunks are wanted")
      .flag("--submit", "submit the script with sbatch and print the job id")
      .epilog(kFarmExitCodes);
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const FarmJob job = jobFrom(parser);
  checkSlurmArraySize(job, parser.has("--max-array-size") ? parser.getInt("--max-array-size", 1)
                                                          : kSlurmDefaultMaxArraySize);
  const std::string logDir = absolute(
      parser.has("--log-dir") ? parser.get("--log-dir")
                              : (fs::path(job.outputPattern).parent_path() / "logs").string());
  const std::string logCulprit =
      parser.has("--log-dir")
          ? culprit("--log-dir", parser.get("--log-dir"))
          : culprit("the log folder (--log-dir, default OUT folder/logs)", logDir);
  // Every value is checked before anything is made or written.
  const std::string script =
      slurmScript(job, slurmLogPattern(logDir, job.name, logCulprit), parser.get("--partition"));
  const std::string jobFile = absolute(parser.get("-O"));
  checkOutputFolderWritable(jobFile);
  checkFarmPaths(parser, job, {{"-O", jobFile, false}});
  // Slurm opens the task logs before the script runs: the folder must exist at submission.
  makeFolder(logDir, "log");
  createOutputFolder(job);
  writeFileAtomically(jobFile, script);
  fs::permissions(jobFile, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                  fs::perm_options::add);
  std::cout << "slurm job: " << jobFile << " (" << job.chunks << " array tasks 0-" << job.chunks - 1
            << ", " << job.frameCount << " frames in chunks of up to " << job.chunkSize << ")\n"
            << "logs:      " << logDir << "/" << safeName(job.name) << "_<job>_<chunk>.log\n";
  submitOrPrintSlurm(parser.has("--submit"), jobFile, "report", "the shot's report",
                     [&](const std::string& id) { return slurmReportOptions(job, id); });
  return 0;
}

/// What lands in the template's format strings and job parameters, checked naming its option.
void checkTemplateOptions(const ArgParser& parser, const FarmJob& job) {
  checkTemplateText(culprit("--job-name", job.name), job.name, "");
  for (const std::string& word : job.extraArgs) {
    checkTemplateText(culprit("--extra-args", parser.get("--extra-args")), word, "\r\n");
  }
  if (job.perChunkReport) {  // the report argument holds the output's name
    checkTemplateText(
        culprit("-o", parser.get("-o")) + " (its name is part of each task's --report argument)",
        sequenceStem(job.outputPattern), "");
  }
  checkTemplatePath(culprit("--db", parser.get("--db")), job.database);
  checkTemplatePath(culprit("--driver", parser.get("--driver")), job.driver);
  checkTemplatePath(culprit("-o", parser.get("-o")), job.outputPattern);
  checkTemplatePath(culprit("--binary", job.binary), job.binary);
}

int runFarmOpenjd(const std::vector<std::string>& args) {
  ArgParser parser(
      "drivenshape farm openjd --db DB --driver CACHE --frames RANGE -o OUT.####.exr "
      "--chunk-size N -O job.template.json",
      "Writes an Open Job Description (2023-09) job template for a shot: one step whose task "
      "parameter Chunk (INT, 0 to chunks-1) selects the chunk of --chunk-size frames each task "
      "bakes. Paths are PATH job parameters (defaults: the absolute paths given here). The "
      "format follows -O: .yaml/.yml writes YAML, anything else JSON. Check and run it with "
      "`openjd check FILE` and `openjd run FILE --step Bake`.");
  addJobOptions(parser);
  parser
      .option("--cancel-grace", "S", "seconds between SIGTERM and SIGKILL when a task is canceled",
              "120")
      .epilog(kFarmExitCodes);
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const FarmJob job = jobFrom(parser);
  if (job.chunks > kOpenJdManyTasks) {
    // IntRangeExpr has no such limit, but render managers cap tasks per step; say so early.
    std::cerr << "warning: " << job.chunks
              << " tasks in one step; render managers may cap this, consider a larger "
                 "--chunk-size\n";
  }
  const long timeout = job.timeLimit.empty() ? 0 : parseTimeLimit(job.timeLimit);
  const int cancelGrace = parser.getInt("--cancel-grace", 1);
  checkCancelGrace(cancelGrace);
  checkTemplateOptions(parser, job);
  const std::string jobFile = absolute(parser.get("-O"));
  nlohmann::ordered_json values = nlohmann::ordered_json::object();
  const nlohmann::ordered_json jobTemplate =
      openJobTemplate(job, fs::path(jobFile).parent_path().string(), timeout, cancelGrace, values);
  checkJobTemplate(jobTemplate);
  const std::string valuesFile = openJobParametersPath(jobFile);
  const std::string text = openJobTemplateText(jobTemplate, jobFile);
  checkOutputFolderWritable(jobFile);
  checkFarmPaths(parser, job,
                 {{"-O", jobFile, false}, {"-O (its job parameters file)", valuesFile, false}});
  createOutputFolder(job);
  // The template names its parameters file: the two change together or not at all.
  writeFilesTogether({{valuesFile, jsonText(values, 2) + "\n"}, {jobFile, text}});
  std::cout << "openjd template: " << jobFile << " (step Bake, " << job.chunks << " tasks Chunk=0-"
            << job.chunks - 1 << ", " << job.frameCount << " frames in chunks of up to "
            << job.chunkSize << "; then step Report, the shot's report)\n"
            << "job parameters: " << valuesFile << "\n"
            << "check with: openjd check " << shellQuote(jobFile) << "\n"
            << "run with:   openjd run " << shellQuote(jobFile) << " --step Bake --job-param "
            << shellQuote("file://" + valuesFile) << "\n"
            << "  and then: openjd run " << shellQuote(jobFile) << " --step Report --job-param "
            << shellQuote("file://" + valuesFile) << "\n";
  return 0;
}

// ---- Simulate jobs (issue 44): a task per window of the plan, then the splice -------------

const char* const kSimulateExitCodes =
    "Task N runs `drivenshape simulate ... --window N` (a window a run before left complete is "
    "kept), the splice task `drivenshape simulate ... --splice-only` (every window must be "
    "there); both plan with the library from the report and the settings, as this command did. "
    "Task exit codes are simulate's: 0 ok, 2 usage, 3 input (a window whose simulation failed, "
    "a window missing for the splice), 4 output. The farm command exits 2 for usage errors, 3 "
    "when an input is missing or nothing is flagged, 4 when the job file or log folder cannot "
    "be written or sbatch fails.";

void addSimulateJobOptions(ArgParser& parser) {
  parser
      .option("--blend", "SHOT.blend", "the shot's scene with the garment's cloth setup", "", true)
      .option("--object", "GARMENT", "the garment object (its Cloth modifier simulates)", "", true)
      .option("--report", "PATH", "the bake's report (bake --report)", "", true)
      .option("--bake", "BAKE.####.exr", "the bake's EXR sequence (every frame of the report)", "",
              true)
      .option("-o", "OUT.####.exr", "output EXR sequence (####, %04d or $F4)", "", true)
      .option("-O", "JOBFILE", "job file to write", "", true)
      .settings(SettingScope::kSimulate)
      .option("--blender", "PATH", "the Blender executable on the workers", "blender on their PATH")
      .option("--job-name", "NAME", "job name", "ds_<output name>_simulate")
      .option("--time", "HH:MM:SS", "time limit per task (also MM or D-HH:MM:SS)")
      .option("--cpus", "N", "CPU cores per task")
      .option("--mem", "MB", "memory per task in MiB")
      .option("--binary", "PATH", "drivenshape executable the tasks run", "this executable")
      .flag("--no-check", "do not check from this machine that the scene and the bake exist");
}

/// The simulate job of the options: the library's plan of the report gives its tasks.
SimulateFarmJob simulateJobFrom(const ArgParser& parser) {
  SimulateFarmJob job;
  job.binary = drivenshapeBinary(parser);
  job.blender = parser.has("--blender") ? parser.get("--blender") : std::string();
  job.blend = absolute(parser.get("--blend"));
  job.object = parser.get("--object");
  job.report = absolute(parser.get("--report"));
  job.bake = absolute(parser.get("--bake"));
  job.outputPattern = absolute(parser.get("-o"));
  job.outputFolder = fs::path(job.outputPattern).parent_path().string();
  SimulationOptions settings;
  readSettings(parser, settings);
  const SimulationPlan plan = planSimulation(readBakeReportCoverage(job.report), settings);
  setSimulateFarmPlan(job, plan);
  job.name = parser.has("--job-name") ? parser.get("--job-name")
                                      : defaultFarmJobName(job.outputPattern) + "_simulate";
  FarmJob names;  // checkFarmJob's checks of the output pattern and the name
  names.outputPattern = job.outputPattern;
  names.name = job.name;
  checkFarmJob(names, parser.get("-o"), plan.first);
  if (!hasFramePattern(job.bake)) {
    DS_THROW(kUsage, culprit("--bake", parser.get("--bake")), " has no frame token");
  }
  if (parser.has("--time")) {
    job.timeLimit = parser.get("--time");
    parseTimeLimit(job.timeLimit);
  }
  job.cpus = parser.has("--cpus") ? parser.getInt("--cpus", 1) : 0;
  job.memoryMb = parser.has("--mem") ? parser.getInt("--mem", 1) : 0;
  if (!parser.has("--no-check")) {
    requireRegularFile(job.binary, "drivenshape executable (--binary)");
    requireRegularFile(job.blend, "scene (--blend)");
    checkSimulationBake(plan, job.bake);
  }
  return job;
}

/// Refuses job files that would overwrite an input of the job.
void checkSimulateFarmPaths(const ArgParser& parser, const SimulateFarmJob& job,
                            const std::vector<NamedPath>& outputs) {
  std::vector<NamedPath> inputs = givenPaths(parser, {"--report", "--blend"});
  const std::vector<NamedPath> bake = givenPaths(parser, {"--bake"}, true);
  inputs.insert(inputs.end(), bake.begin(), bake.end());
  inputs.push_back({"--binary", job.binary, false});
  checkDistinctPaths(outputs, {}, inputs);
}

int runFarmSlurmSimulate(const std::vector<std::string>& args) {
  ArgParser parser(
      "drivenshape farm slurm simulate --blend SHOT.blend --object GARMENT --report "
      "BAKE.report.json --bake BAKE.####.exr -o OUT.####.exr -O job.sbatch",
      "Writes an sbatch array script that simulates the frames a bake's verdict flags: one "
      "array task per window of the simulation plan (array indices 1..windows), and with the "
      "argument `splice` the splice of every window into -o, submitted after them. --submit "
      "runs sbatch for both and prints their job ids.");
  addSimulateJobOptions(parser);
  parser.option("--partition", "P", "Slurm partition")
      .option("--log-dir", "DIR", "folder of the per-task logs (NAME_JOBID_WINDOW.log)",
              "OUT folder/logs")
      .flag("--submit", "submit the script with sbatch and print the job ids")
      .epilog(kSimulateExitCodes);
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const SimulateFarmJob job = simulateJobFrom(parser);
  const std::string logDir =
      absolute(parser.has("--log-dir") ? parser.get("--log-dir") : job.outputFolder + "/logs");
  const std::string logCulprit = culprit("--log-dir (default OUT folder/logs)", logDir);
  const std::string script = slurmSimulateScript(job, slurmLogPattern(logDir, job.name, logCulprit),
                                                 parser.get("--partition"));
  const std::string jobFile = absolute(parser.get("-O"));
  checkOutputFolderWritable(jobFile);
  checkSimulateFarmPaths(parser, job, {{"-O", jobFile, false}});
  makeFolder(logDir, "log");
  std::error_code ec;
  fs::create_directories(job.outputFolder, ec);
  writeFileAtomically(jobFile, script);
  fs::permissions(jobFile, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                  fs::perm_options::add);
  std::cout << "slurm job: " << jobFile << " (" << job.windows << " array tasks 1-" << job.windows
            << ", one per window of frames " << job.firstFrame << "-" << job.lastFrame
            << "; then the splice)\n"
            << "logs:      " << logDir << "/" << safeName(job.name) << "_<job>_<window>.log\n";
  submitOrPrintSlurm(parser.has("--submit"), jobFile, "splice", "the splice",
                     [&](const std::string& id) { return slurmSpliceOptions(job, id); });
  return 0;
}

int runFarmOpenjdSimulate(const std::vector<std::string>& args) {
  ArgParser parser(
      "drivenshape farm openjd simulate --blend SHOT.blend --object GARMENT --report "
      "BAKE.report.json --bake BAKE.####.exr -o OUT.####.exr -O job.template.json",
      "Writes an Open Job Description (2023-09) job template that simulates the frames a "
      "bake's verdict flags: step Simulate, one task per window of the simulation plan (task "
      "parameter Window, 1..windows), and step Splice after it. Paths are PATH job parameters; "
      "the format follows -O (.yaml/.yml: YAML, else JSON).");
  addSimulateJobOptions(parser);
  parser
      .option("--cancel-grace", "S", "seconds between SIGTERM and SIGKILL when a task is canceled",
              "120")
      .epilog(kSimulateExitCodes);
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const SimulateFarmJob job = simulateJobFrom(parser);
  const long timeout = job.timeLimit.empty() ? 0 : parseTimeLimit(job.timeLimit);
  const int cancelGrace = parser.getInt("--cancel-grace", 1);
  checkCancelGrace(cancelGrace);
  checkTemplateText(culprit("--job-name", job.name), job.name, "");
  checkTemplateText(culprit("--object", job.object), job.object, "");
  checkTemplateText(culprit("--blender", job.blender), job.blender, "");
  for (const auto& [option, path] : {std::pair<const char*, std::string>{"--blend", job.blend},
                                     {"--report", job.report},
                                     {"--bake", job.bake},
                                     {"-o", job.outputPattern},
                                     {"--binary", job.binary}}) {
    checkTemplatePath(culprit(option, path), path);
  }
  const std::string jobFile = absolute(parser.get("-O"));
  nlohmann::ordered_json values = nlohmann::ordered_json::object();
  const nlohmann::ordered_json jobTemplate = openJobSimulateTemplate(
      job, fs::path(jobFile).parent_path().string(), timeout, cancelGrace, values);
  checkJobTemplate(jobTemplate);
  const std::string valuesFile = openJobParametersPath(jobFile);
  checkOutputFolderWritable(jobFile);
  checkSimulateFarmPaths(
      parser, job, {{"-O", jobFile, false}, {"-O (its job parameters file)", valuesFile, false}});
  writeFilesTogether({{valuesFile, jsonText(values, 2) + "\n"},
                      {jobFile, openJobTemplateText(jobTemplate, jobFile)}});
  std::cout << "openjd template: " << jobFile << " (step Simulate, " << job.windows
            << " tasks Window=1-" << job.windows << "; then step Splice)\n"
            << "job parameters: " << valuesFile << "\n"
            << "run with:   openjd run " << shellQuote(jobFile) << " --step Simulate --job-param "
            << shellQuote("file://" + valuesFile) << "\n"
            << "  and then: openjd run " << shellQuote(jobFile) << " --step Splice --job-param "
            << shellQuote("file://" + valuesFile) << "\n";
  return 0;
}

}  // namespace

int runFarm(const std::vector<std::string>& args) {
  constexpr const char* kFarmUsage =
      "usage: drivenshape farm slurm|openjd [options]   (drivenshape farm slurm --help)\n"
      "\n"
      "  slurm    write (and with --submit, submit) an sbatch array script, one task per chunk\n"
      "  openjd   write an Open Job Description job template, one task per chunk\n"
      "  slurm simulate, openjd simulate\n"
      "           the same for `drivenshape simulate`: one task per window of the simulation\n"
      "           plan, then the splice (drivenshape farm slurm simulate --help)\n";
  if (args.empty()) {
    DS_THROW(kUsage, "`drivenshape farm` needs a scheduler: slurm or openjd");
  }
  if (args[0] == "-h" || args[0] == "--help") {
    std::cout << kFarmUsage;
    return 0;
  }
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (!rest.empty() && rest[0] == "simulate" && (args[0] == "slurm" || args[0] == "openjd")) {
    const std::vector<std::string> words(rest.begin() + 1, rest.end());
    return args[0] == "slurm" ? runFarmSlurmSimulate(words) : runFarmOpenjdSimulate(words);
  }
  if (args[0] == "slurm") {
    return runFarmSlurm(rest);
  }
  if (args[0] == "openjd") {
    return runFarmOpenjd(rest);
  }
  DS_THROW(kUsage, "unknown scheduler '", args[0], "' for `drivenshape farm`: slurm or openjd");
}

}  // namespace drivenshape::cli
