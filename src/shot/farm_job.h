// SPDX-License-Identifier: Apache-2.0
#pragma once

// The farm job of a shot (`drivenshape farm slurm|openjd`): one bake per chunk of the shot's
// frames (`bake --chunk-size N --chunk-index I --skip-existing`), so that a killed or retried
// task resumes where it stopped. Written as a Slurm sbatch array script (one array task per
// chunk) or an Open Job Description 2023-09 job template (task parameter Chunk). The command
// (apps/farm_command.cpp) reads its options into a FarmJob, calls these and writes the files.
//
// Messages name the farm command's options (the job's values come from them), and the errors
// keep its exit codes: Error(kUsage) for a value no scheduler can carry, kInput for a missing
// input, kOutput when sbatch fails, kInternal for a template that would fail `openjd check`.

#include <nlohmann/json.hpp>
#include <ostream>
#include <string>
#include <vector>

#include <drivenshape/simulation.h>

namespace drivenshape {

/// What both schedulers need: one bake command per chunk, everything absolute.
struct FarmJob {
  std::string binary;         ///< absolute path of the drivenshape executable
  std::string database;       ///< absolute
  std::string driver;         ///< absolute .pc2 or EXR sequence pattern
  std::string frames;         ///< --frames as given (validated)
  std::string framesText;     ///< --frames for comments and descriptions, at most 200 bytes
  std::string outputPattern;  ///< absolute, with a frame token
  std::string outputFolder;   ///< absolute folder of outputPattern
  /// Each task's JSON report, `<output folder>/<stem>.chunk<I>.report.json` (tasks run side by
  /// side, so one shared report path would keep only the last task's), unless --extra-args
  /// names --report itself.
  bool perChunkReport = true;
  int frameCount = 0;
  int chunkSize = 0;
  int chunks = 0;
  std::string name;
  std::vector<std::string> extraArgs;
  std::string timeLimit;  ///< Slurm form, empty when not given
  int cpus = 0;           ///< 0 when not given
  int memoryMb = 0;       ///< 0 when not given
};

/// The farm job of `drivenshape simulate` (issue 44): a task per window of the library's plan,
/// `simulate ... --window N` (N = 1..windows; a window a run before left complete is kept), and
/// after every window the splice task, `simulate ... --splice-only`. Both run the same command
/// with the same settings, so the tasks plan what the job was written from.
struct SimulateFarmJob {
  std::string binary;         ///< absolute path of the drivenshape executable
  std::string blender;        ///< Blender on the workers; empty: `blender` on their PATH
  std::string blend;          ///< absolute
  std::string object;         ///< the garment
  std::string report;         ///< absolute: the bake's report
  std::string bake;           ///< absolute EXR sequence pattern
  std::string outputPattern;  ///< absolute, with a frame token
  std::string outputFolder;   ///< absolute folder of outputPattern
  std::string name;
  /// Every simulation setting of the plan as command-line words (simulationSettingArgs).
  std::vector<std::string> settingArgs;
  int windows = 0;     ///< the plan's windows: the tasks
  int firstFrame = 0;  ///< the shot's frames, for descriptions
  int lastFrame = 0;
  std::string timeLimit;  ///< Slurm form, empty when not given
  int cpus = 0;           ///< 0 when not given
  int memoryMb = 0;       ///< 0 when not given
};

/// The settings of `settings` as `drivenshape simulate` words, every setting of the settings
/// table's kSimulate rows (a kBool's flag when it is not the default): "--warmup 20 ...".
std::vector<std::string> simulationSettingArgs(const SimulationOptions& settings);

/// The job's tasks from the library's plan: its window count, frames and settings.
/// Error(kInput) naming the report when the plan has no window (nothing flagged: run
/// `drivenshape simulate` where it is, which writes the bake's frames).
void setSimulateFarmPlan(SimulateFarmJob& job, const SimulationPlan& plan);

/// The task of window `window` (a number, `env` or a template token) as argv words.
std::vector<std::string> simulateWindowCommand(const SimulateFarmJob& job,
                                               const std::string& window);
/// The splice task as argv words.
std::vector<std::string> simulateSpliceCommand(const SimulateFarmJob& job);

// ---- The job -------------------------------------------------------------------------------

/// POSIX shell single quoting: 'it'\''s'.
std::string shellQuote(const std::string& word);

/// A name safe in file names and scheduler job names: letters, digits, '.', '_', '-'.
std::string safeName(const std::string& text);

/// `option 'value'` for messages, on one line: control characters (C0, DEL and C1) shown as
/// their bytes, \xNN.
std::string culprit(const std::string& option, const std::string& value);

/// Seconds in a Slurm time limit: MM, MM:SS, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS; anything
/// else is Error(kUsage) naming --time.
long parseTimeLimit(const std::string& text);

/// The job name when --job-name is not given: `ds_<output name>`.
std::string defaultFarmJobName(const std::string& outputPattern);

/// The chunk plan of `frames` (--frames parsed, job.frames as given) in chunks of
/// job.chunkSize: sets job.frameCount, job.framesText and job.chunks.
void planFarmChunks(FarmJob& job, const std::vector<int>& frames);

/// The output pattern and the job name, before any job is written: job.outputPattern has
/// exactly one frame token, as the bake checks it (`givenOutput` is -o as given, for the
/// message; `firstFrame` the shot's first frame), and job.name is 1 to 128 printable bytes.
/// Error(kUsage) otherwise.
void checkFarmJob(const FarmJob& job, const std::string& givenOutput, int firstFrame);

/// --extra-args split into job.extraArgs (shell-like words: whitespace, quotes, backslash; no
/// expansion). Refuses the options the farm command sets itself, and turns off the per-chunk
/// reports when the words hold a --report of the user's.
void setFarmExtraArgs(FarmJob& job, const std::string& extraArgs);

/// From this machine: the executable and the database exist, the driver has every frame.
void checkFarmInputs(const FarmJob& job, const std::vector<int>& frames);

/// The bake of one chunk as argv words; `chunkIndex` is a number, `env` or a template token.
std::vector<std::string> chunkBakeCommand(const FarmJob& job, const std::string& chunkIndex);

/// The job's last task, after every chunk: the bake of the whole shot with its outputs kept
/// (--skip-existing), which checks every frame, bakes none when the chunks did theirs, and
/// writes the shot's report (<output folder>/<stem>.report.json, or the --report of
/// --extra-args) from the records the frames carry: the report of a one-shot bake.
std::vector<std::string> shotReportCommand(const FarmJob& job);

// ---- Slurm ---------------------------------------------------------------------------------

/// Slurm's default MaxArraySize: array indices 0..1000.
constexpr int kSlurmDefaultMaxArraySize = 1001;

/// Error(kUsage) when the job has more chunks than the cluster's MaxArraySize allows.
void checkSlurmArraySize(const FarmJob& job, int maxArraySize);

/// The `--output` pattern of the task logs, `logDir/NAME_%A_%a.log`, as an #SBATCH value:
/// every '%' of the folder doubled (Slurm's literal '%'). A backslash is refused: in a path
/// Slurm turns its %A/%a replacement off (and the task fails to launch). `who` names the
/// folder in messages.
std::string slurmLogPattern(const std::string& logDir, const std::string& jobName,
                            const std::string& who);

/// The sbatch array script: one array task per chunk, its log at `logPattern` (from
/// slurmLogPattern), on `partition` when not empty, SIGTERM and SIGINT passed on to the bake.
/// Every value of an #SBATCH line is checked (Error(kUsage) naming its option).
std::string slurmScript(const FarmJob& job, const std::string& logPattern,
                        const std::string& partition);

/// The sbatch array script of a simulate job: array task N (1..windows) simulates window N,
/// the script with the argument `splice` splices; otherwise as slurmScript.
std::string slurmSimulateScript(const SimulateFarmJob& job, const std::string& logPattern,
                                const std::string& partition);

/// Runs `sbatch --parsable OPTIONS SCRIPT ARGS` (through the shell, each word quoted, waiting
/// for it) and returns the job id it prints; Error(kOutput) when sbatch cannot run, fails or
/// prints no id.
std::string submitToSlurm(const std::string& script, const std::vector<std::string>& options = {},
                          const std::vector<std::string>& scriptArgs = {});

/// The sbatch options of the shot's report task (the script run with the argument `report`):
/// after every chunk of array job `arrayJob` succeeded, one task, its own job name.
std::vector<std::string> slurmReportOptions(const FarmJob& job, const std::string& arrayJob);

/// The sbatch options of a simulate job's splice task (the script run with the argument
/// `splice`): after every window task of array job `arrayJob` succeeded, one task.
std::vector<std::string> slurmSpliceOptions(const SimulateFarmJob& job,
                                            const std::string& arrayJob);

// ---- Open Job Description ------------------------------------------------------------------

/// Render managers cap the tasks of a step; more chunks than this are worth a warning.
constexpr int kOpenJdManyTasks = 1024;

/// Error(kUsage) when --cancel-grace is beyond the notify period the spec allows (600 s).
void checkCancelGrace(int seconds);

/// A value of the command line that lands in a format string of the template (the job name,
/// an argument of the bake): Open Job Description reads `{{`...`}}` there as an expression and
/// has no escape for the braces, and allows no control characters but `allowedControls`.
/// Refused with Error(kUsage) naming `who`.
void checkTemplateText(const std::string& who, const std::string& text,
                       const std::string& allowedControls);

/// A path that becomes a job parameter value: UTF-8 (the template and its values are UTF-8
/// text, other bytes would change the path) of at most 1024 characters. Error(kUsage) naming
/// `who` otherwise.
void checkTemplatePath(const std::string& who, const std::string& path);

/// The template. PATH parameters (path-mapped by render managers) hold the data. The spec
/// only allows relative defaults that stay inside the template's folder `templateDir` (they are
/// joined to it when a job is created), so a path gets a default only there; every path's
/// absolute value also goes into `values`, the job parameter values file written beside the
/// template. The executable is a STRING: it is where drivenshape is installed on the workers,
/// not data to map. `timeoutSeconds` 0: no timeout.
nlohmann::ordered_json openJobTemplate(const FarmJob& job, const std::string& templateDir,
                                       long timeoutSeconds, int notifySeconds,
                                       nlohmann::ordered_json& values);

/// The template's own check before it is written: what openjd-model (`openjd check`) refuses
/// in the fields openJobTemplate writes. Every string UTF-8; the format strings (name,
/// command, arguments, environment variables) with balanced `{{ }}` around only the
/// expressions it writes (the job's parameters, the step's task parameters, the session
/// folder) and no control characters (arguments may break lines); names, descriptions and
/// parameter defaults within their lengths; the notify period within 1..600 s. The checks of
/// the options come first and name the option, so a failure here is a bug: Error(kInternal).
void checkJobTemplate(const nlohmann::ordered_json& jobTemplate);

/// The template of a simulate job: step Simulate (task parameter Window, 1..windows) and step
/// Splice after it; paths as openJobTemplate's (PATH parameters, their values in `values`).
nlohmann::ordered_json openJobSimulateTemplate(const SimulateFarmJob& job,
                                               const std::string& templateDir, long timeoutSeconds,
                                               int notifySeconds, nlohmann::ordered_json& values);

/// Block-style YAML of a JSON value. Strings are written as JSON strings, which YAML reads as
/// double-quoted scalars with the same escapes, so no value can change meaning.
void writeYaml(std::ostream& out, const nlohmann::ordered_json& value, int indent,
               bool inlineFirst);

/// The text of the template file `jobFile`: YAML (with a comment naming this version) when it
/// ends in .yaml or .yml, else indented JSON.
std::string openJobTemplateText(const nlohmann::ordered_json& jobTemplate,
                                const std::string& jobFile);

/// The job parameter values file beside `jobFile`: shot.template.json ->
/// shot.template.params.json (also for .yaml/.yml and no extension).
std::string openJobParametersPath(const std::string& jobFile);

}  // namespace drivenshape
