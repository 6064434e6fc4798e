// SPDX-License-Identifier: Apache-2.0
// The farm job of a shot (farm_job.h): the chunks' bake command, the Slurm sbatch array script
// and its submission, the Open Job Description 2023-09 template, its checks and its YAML.

#include "farm_job.h"

#include <sys/wait.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <set>
#include <sstream>
#include <string_view>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/settings_table.h>
#include <drivenshape/simulation.h>
#include <drivenshape/version.h>

#include "json_text.h"
#include "text.h"

namespace drivenshape {
namespace {

namespace fs = std::filesystem;

/// Bake options the farm command sets itself on every task; --extra-args must not repeat them.
const char* const kReservedBakeOptions[] = {"--db",         "--driver",      "--frames",       "-o",
                                            "--chunk-size", "--chunk-index", "--skip-existing"};

/// Splits --extra-args like a shell would for plain words: whitespace separates words, single
/// and double quotes group them, backslash escapes one character. No expansion of any kind.
std::vector<std::string> splitWords(const std::string& text) {
  std::vector<std::string> words;
  std::string word;
  bool inWord = false;
  char quote = '\0';
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quote != '\0') {
      if (c == quote) {
        quote = '\0';
      } else if (c == '\\' && quote == '"' && i + 1 < text.size()) {
        word += text[++i];
      } else {
        word += c;
      }
    } else if (c == '\'' || c == '"') {
      quote = c;
      inWord = true;
    } else if (c == '\\' && i + 1 < text.size()) {
      word += text[++i];
      inWord = true;
    } else if (std::isspace(static_cast<unsigned char>(c))) {
      if (inWord) {
        words.push_back(word);
        word.clear();
        inWord = false;
      }
    } else {
      word += c;
      inWord = true;
    }
  }
  if (quote != '\0') {
    DS_THROW(kUsage, "--extra-args '", text, "' has an unclosed ", quote, " quote");
  }
  if (inWord) {
    words.push_back(word);
  }
  return words;
}

/// True when `text` holds a control character other than those in `allowed`: C0 (below 0x20),
/// DEL, or C1 (U+0080-U+009F, in UTF-8 the bytes C2 80-C2 9F).
bool hasControlCharacter(const std::string& text, const std::string& allowed = std::string()) {
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto byte = static_cast<unsigned char>(text[i]);
    const bool c1 = byte == 0xC2 && i + 1 < text.size() &&
                    static_cast<unsigned char>(text[i + 1]) >= 0x80 &&
                    static_cast<unsigned char>(text[i + 1]) <= 0x9F;
    if ((byte < 0x20 || byte == 0x7F || c1) && allowed.find(text[i]) == std::string::npos) {
      return true;
    }
  }
  return false;
}

}  // namespace

/// POSIX shell single quoting: 'it'\''s'.
std::string shellQuote(const std::string& word) {
  std::string quoted = "'";
  for (char c : word) {
    if (c == '\'') {
      quoted += "'\\''";
    } else {
      quoted += c;
    }
  }
  return quoted + "'";
}

/// Seconds in a Slurm time limit: MM, MM:SS, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS.
long parseTimeLimit(const std::string& text) {
  auto fail = [&]() {
    DS_THROW(kUsage, "--time '", text, "' is not a time limit; use HH:MM:SS, MM or D-HH:MM:SS");
  };
  std::string rest = text;
  long days = -1;
  if (const auto dash = rest.find('-'); dash != std::string::npos) {
    const std::string dayText = rest.substr(0, dash);
    if (dayText.empty() || dayText.size() > 6 ||
        !std::all_of(dayText.begin(), dayText.end(), ::isdigit)) {
      fail();
    }
    days = std::stol(dayText);
    rest = rest.substr(dash + 1);
  }
  std::vector<long> parts;
  std::stringstream stream(rest);
  std::string part;
  while (std::getline(stream, part, ':')) {
    if (part.empty() || part.size() > 6 || !std::all_of(part.begin(), part.end(), ::isdigit)) {
      fail();
    }
    parts.push_back(std::stol(part));
  }
  if (parts.empty() || parts.size() > 3 || (!rest.empty() && rest.back() == ':')) {
    fail();
  }
  // Each field after the first counts within the one before: 0-59 (hours after days: 0-23).
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const bool hours = days >= 0 && i == 0;
    const long most = hours ? 23 : 59;
    if ((i > 0 || hours) && parts[i] > most) {
      DS_THROW(kUsage, "--time '", text, "': ", hours ? "hours " : "minutes or seconds ", parts[i],
               " is past ", most, "; use HH:MM:SS, MM or D-HH:MM:SS");
    }
  }
  long seconds = 0;
  if (days >= 0) {  // D-HH[:MM[:SS]]
    seconds = days * 86400 + parts[0] * 3600 + (parts.size() > 1 ? parts[1] * 60 : 0) +
              (parts.size() > 2 ? parts[2] : 0);
  } else if (parts.size() == 1) {  // MM
    seconds = parts[0] * 60;
  } else if (parts.size() == 2) {  // MM:SS
    seconds = parts[0] * 60 + parts[1];
  } else {  // HH:MM:SS
    seconds = parts[0] * 3600 + parts[1] * 60 + parts[2];
  }
  if (seconds <= 0) {
    fail();
  }
  return seconds;
}

/// A name safe in file names and scheduler job names: letters, digits, '.', '_', '-'.
std::string safeName(const std::string& text) {
  std::string name;
  for (char c : text) {
    const bool ok = std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-';
    name += ok ? c : '_';
  }
  return name.empty() ? std::string("drivenshape") : name;
}

/// `option 'value'` for messages, on one line: control characters (C0, DEL and C1) shown as
/// their bytes, \xNN.
std::string culprit(const std::string& option, const std::string& value) {
  const auto hex = [](unsigned char byte) {
    const char* digits = "0123456789abcdef";
    return std::string("\\x") + digits[byte >> 4] + digits[byte & 15];
  };
  std::string text = option + " '";
  for (std::size_t i = 0; i < value.size(); ++i) {
    const auto byte = static_cast<unsigned char>(value[i]);
    const auto next = i + 1 < value.size() ? static_cast<unsigned char>(value[i + 1]) : 0;
    if (byte < 0x20 || byte == 0x7F) {
      text += hex(byte);
    } else if (byte == 0xC2 && next >= 0x80 && next <= 0x9F) {
      text += hex(byte) + hex(next);
      ++i;
    } else {
      text += value[i];
    }
  }
  return text + "'";
}

std::string defaultFarmJobName(const std::string& outputPattern) {
  return "ds_" + safeName(sequenceStem(outputPattern));
}

void planFarmChunks(FarmJob& job, const std::vector<int>& frames) {
  job.frameCount = static_cast<int>(frames.size());
  job.framesText = job.frames;
  if (job.framesText.size() > 200) {  // a long list of frames
    job.framesText = "frames " + std::to_string(*std::min_element(frames.begin(), frames.end())) +
                     " to " + std::to_string(*std::max_element(frames.begin(), frames.end()));
  }
  job.chunks = (job.frameCount + job.chunkSize - 1) / job.chunkSize;
}

void checkFarmJob(const FarmJob& job, const std::string& givenOutput, int firstFrame) {
  if (!hasFramePattern(job.outputPattern)) {
    DS_THROW(kUsage, "-o '", givenOutput, "' has no frame token; use e.g. out/cloth.####.exr");
  }
  // What the bake checks of its (absolute) pattern, with the bake's own function: exactly one
  // frame token in the whole path (a '#' in a folder name counts). Every task's bake would exit
  // 2 on a pattern it refuses, so the farm command refuses it before writing a job.
  try {
    expandFramePattern(job.outputPattern, firstFrame);
  } catch (const Error& error) {
    throw Error(error.code(), "-o '" + givenOutput + "': " + error.what() +
                                  "; every task's bake would refuse it");
  }
  if (job.name.empty() || job.name.size() > 128 || hasControlCharacter(job.name)) {
    DS_THROW(kUsage, culprit("--job-name", job.name), ": a job name is 1 to 128 printable bytes");
  }
}

void setFarmExtraArgs(FarmJob& job, const std::string& extraArgs) {
  job.extraArgs = splitWords(extraArgs);
  for (const std::string& word : job.extraArgs) {
    const std::string name = word.substr(0, word.find('='));
    if (name == "--report") {
      job.perChunkReport = false;
    }
    for (const char* reserved : kReservedBakeOptions) {
      if (name == reserved) {
        DS_THROW(kUsage, "--extra-args must not hold ", reserved,
                 ": the farm command sets it on every task");
      }
    }
  }
}

/// From this machine: the executable and the database exist, the driver has every frame.
void checkFarmInputs(const FarmJob& job, const std::vector<int>& frames) {
  std::error_code ec;
  if (!fs::is_regular_file(job.binary, ec)) {
    DS_THROW(kInput, "drivenshape executable '", job.binary, "' does not exist");
  }
  if (!fs::is_regular_file(job.database, ec)) {
    DS_THROW(kInput, "database '", job.database,
             "' does not exist (or pass --no-check when only the farm can see it)");
  }
  const auto driver = openPointCache(job.driver);
  std::vector<int> missing;
  for (int frame : frames) {
    if (!driver->hasFrame(frame)) {
      missing.push_back(frame);
    }
  }
  if (!missing.empty()) {
    DS_THROW(kInput, "driver cache '", job.driver, "' lacks frames ", formatFrameRange(missing),
             " of --frames ", job.frames, "; fix the range or the cache");
  }
}

namespace {

/// The bake of the job's shot as argv words, up to its output (the words every task has).
std::vector<std::string> shotBakeWords(const FarmJob& job) {
  return {job.binary, "bake",     "--db",     job.database, "--driver",
          job.driver, "--frames", job.frames, "-o",         job.outputPattern};
}

}  // namespace

/// The bake of one chunk as argv words; `chunkIndex` is a number, `env` or a template token.
std::vector<std::string> chunkBakeCommand(const FarmJob& job, const std::string& chunkIndex) {
  std::vector<std::string> words = shotBakeWords(job);
  for (const std::string& word :
       {std::string("--chunk-size"), std::to_string(job.chunkSize), std::string("--chunk-index"),
        chunkIndex, std::string("--skip-existing")}) {
    words.push_back(word);
  }
  words.insert(words.end(), job.extraArgs.begin(), job.extraArgs.end());
  return words;
}

std::vector<std::string> shotReportCommand(const FarmJob& job) {
  std::vector<std::string> words = shotBakeWords(job);
  words.push_back("--skip-existing");
  words.insert(words.end(), job.extraArgs.begin(), job.extraArgs.end());
  return words;
}

std::vector<std::string> simulationSettingArgs(const SimulationOptions& settings) {
  std::vector<std::string> words;
  for (const Setting* setting : settingsOfScope(SettingScope::kSimulate)) {
    if (setting->flag == nullptr) {
      continue;
    }
    const SettingValue value = settingValue(*setting, settings);
    if (setting->type == SettingType::kBool) {
      if (value != defaultSettingValue(*setting)) {
        words.emplace_back(setting->flag);
      }
    } else {
      words.emplace_back(setting->flag);
      words.push_back(formatSettingValue(*setting, value));
    }
  }
  return words;
}

void setSimulateFarmPlan(SimulateFarmJob& job, const SimulationPlan& plan) {
  if (plan.windows.empty()) {
    DS_THROW(kInput, "the report ", plan.report, " flags no frame of ", plan.first, "-", plan.last,
             ", so the plan has no window to simulate and the farm job no task; run "
             "`drivenshape simulate` where it is (it writes the bake's frames)");
  }
  job.windows = static_cast<int>(plan.windows.size());
  job.firstFrame = plan.first;
  job.lastFrame = plan.last;
  job.settingArgs = simulationSettingArgs(plan.settings);
}

namespace {

/// `drivenshape simulate` of the job's shot as argv words, with every setting (the words every
/// task has).
std::vector<std::string> shotSimulateWords(const SimulateFarmJob& job) {
  std::vector<std::string> words = {job.binary, "simulate", "--blend",  job.blend,
                                    "--object", job.object, "--report", job.report,
                                    "--bake",   job.bake,   "-o",       job.outputPattern};
  words.insert(words.end(), job.settingArgs.begin(), job.settingArgs.end());
  if (!job.blender.empty()) {
    words.emplace_back("--blender");
    words.push_back(job.blender);
  }
  return words;
}

}  // namespace

std::vector<std::string> simulateWindowCommand(const SimulateFarmJob& job,
                                               const std::string& window) {
  std::vector<std::string> words = shotSimulateWords(job);
  words.emplace_back("--window");
  words.push_back(window);
  return words;
}

std::vector<std::string> simulateSpliceCommand(const SimulateFarmJob& job) {
  std::vector<std::string> words = shotSimulateWords(job);
  words.emplace_back("--splice-only");
  return words;
}

// ---- Slurm -------------------------------------------------------------------------------

namespace {

/// The value of an `#SBATCH --name=value` line, one rule for every value that lands in one:
/// a control character (a line break would end the line) is refused naming `who` (the option
/// it comes from, and its value); a value of plain characters is written as it is; any
/// other is double-quoted with '"' and '\' escaped by a backslash, which sbatch reads back
/// exactly (unquoted, a space ends the value and a '#' starts a comment).
std::string sbatchValue(const std::string& value, const std::string& who) {
  if (hasControlCharacter(value)) {
    DS_THROW(kUsage, who,
             " holds a control character (a line break, tab, ...), which an "
             "#SBATCH line cannot carry; choose another value");
  }
  const bool plain = !value.empty() && std::all_of(value.begin(), value.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) ||
           std::string_view("._-+,:/=@%").find(c) != std::string_view::npos;
  });
  if (plain) {
    return value;
  }
  std::string quoted = "\"";
  for (char c : value) {
    if (c == '"' || c == '\\') {
      quoted += '\\';
    }
    quoted += c;
  }
  return quoted + "\"";
}

}  // namespace

void checkSlurmArraySize(const FarmJob& job, int maxArraySize) {
  if (job.chunks > maxArraySize) {
    DS_THROW(kUsage, job.frameCount, " frames in chunks of ", job.chunkSize, " make ", job.chunks,
             " array tasks, more than Slurm's MaxArraySize of ", maxArraySize,
             "; raise --chunk-size to at least ",
             (job.frameCount + maxArraySize - 1) / maxArraySize,
             ", or pass --max-array-size if the cluster allows more");
  }
}

/// The `--output` pattern of the task logs, `logDir/NAME_%A_%a.log`, as an #SBATCH value:
/// every '%' of the folder doubled (Slurm's literal '%'). A backslash is refused: in a path
/// Slurm turns its %A/%a replacement off (and the task fails to launch).
std::string slurmLogPattern(const std::string& logDir, const std::string& jobName,
                            const std::string& who) {
  if (logDir.find('\\') != std::string::npos) {
    DS_THROW(kUsage, who,
             " holds a backslash, which Slurm's log file names cannot carry "
             "(it turns off their %A/%a replacement); choose another folder");
  }
  std::string pattern;
  for (char c : logDir) {
    pattern += c;
    if (c == '%') {
      pattern += '%';
    }
  }
  return sbatchValue(pattern + "/" + safeName(jobName) + "_%A_%a.log", who);
}

namespace {

/// The #SBATCH lines of an array job (array `array`, e.g. "0-2") and its resources.
void writeSbatchLines(std::ostream& s, const std::string& name, const std::string& array,
                      const std::string& logPattern, const std::string& partition,
                      const std::string& timeLimit, int cpus, int memoryMb) {
  s << "#SBATCH --job-name=" << sbatchValue(name, culprit("--job-name", name)) << "\n"
    << "#SBATCH --array=" << array << "\n"
    << "#SBATCH --output=" << logPattern << "\n"
    << "#SBATCH --open-mode=append\n"
    << "#SBATCH --ntasks=1\n";
  if (!partition.empty()) {
    s << "#SBATCH --partition=" << sbatchValue(partition, culprit("--partition", partition))
      << "\n";
  }
  if (!timeLimit.empty()) {
    s << "#SBATCH --time=" << sbatchValue(timeLimit, culprit("--time", timeLimit)) << "\n";
  }
  if (cpus > 0) {
    s << "#SBATCH --cpus-per-task=" << cpus << "\n";
  }
  if (memoryMb > 0) {
    s << "#SBATCH --mem=" << memoryMb << "\n";
  }
}

/// `  set -- 'word' 'word' ...` (no line break).
void writeSetArgs(std::ostream& s, const std::vector<std::string>& words) {
  s << "  set --";
  for (const std::string& word : words) {
    s << " " << shellQuote(word);
  }
}

/// The end of a task script: runs "$@" in the background (in `child`), passes SIGTERM and
/// SIGINT on to it and exits with its code. `comment`: what the child does with a signal.
void writeSlurmRunTail(std::ostream& s, const std::string& child, const std::string& comment) {
  s << "echo \"drivenshape farm: job ${SLURM_ARRAY_JOB_ID:-?} $task on $(hostname) at "
    << "$(date '+%F %T')\"\n"
    << "\n"
    << comment << "\"$@\" &\n"
    << child << "=$!\n"
    << "signalled=0\n"
    << "forward() { signalled=1; kill -s \"$1\" \"$" << child << "\" 2>/dev/null || true; }\n"
    << "trap 'forward TERM' TERM\n"
    << "trap 'forward INT' INT\n"
    << "wait \"$" << child << "\"\n"
    << "status=$?\n"
    << "# A trapped signal ends `wait` early (status > 128): wait again for the " << child
    << "'s own code.\n"
    << "while [ \"$signalled\" -eq 1 ]; do\n"
    << "  signalled=0\n"
    << "  wait \"$" << child << "\"\n"
    << "  status=$?\n"
    << "done\n"
    << "echo \"drivenshape farm: $task exited with $status at "
    << "$(date '+%F %T')\"\n"
    << "exit \"$status\"\n";
}

}  // namespace

std::string slurmScript(const FarmJob& job, const std::string& logPattern,
                        const std::string& partition) {
  const std::string last = std::to_string(job.chunks - 1);
  std::ostringstream s;
  s << "#!/bin/bash\n"
    << "# Written by drivenshape " << kVersion << " (`drivenshape farm slurm`): " << job.frameCount
    << " frames (" << job.framesText << ") in " << job.chunks << " chunks of up to "
    << job.chunkSize << ".\n"
    << "# Array index I is a chunk number, never a frame number: task I bakes frames\n"
    << "# [I*" << job.chunkSize << ", (I+1)*" << job.chunkSize
    << ") of the range. Every task passes --skip-existing, so a requeued or\n"
    << "# resubmitted task keeps its finished frames; resubmit failed chunks with\n"
    << "#   sbatch --array=I,J "
    << "<this file>\n"
    << "# With the argument `report` (after the chunks: sbatch --dependency=afterok:JOB\n"
    << "# --array=0 <this file> report) it writes the shot's report from every frame's record.\n";
  writeSbatchLines(s, job.name, "0-" + last, logPattern, partition, job.timeLimit, job.cpus,
                   job.memoryMb);
  s << "set -u\n"
    << "\n"
    << "# PoCL compiles kernels into a cache; keep it in a folder this task can write.\n"
    << "if [ -z \"${POCL_CACHE_DIR:-}\" ] || ! mkdir -p \"$POCL_CACHE_DIR\" 2>/dev/null ||\n"
    << "   [ ! -w \"$POCL_CACHE_DIR\" ]; then\n"
    << "  export POCL_CACHE_DIR=\"${TMPDIR:-/tmp}/drivenshape-pocl-$(id -u)\"\n"
    << "  mkdir -p \"$POCL_CACHE_DIR\"\n"
    << "fi\n"
    << "export POCL_CACHE_DIR\n"
    << "mkdir -p " << shellQuote(job.outputFolder) << "\n"
    << "if [ \"${1:-}\" = report ]; then\n"
    << "  task=\"the shot's report\"\n";
  writeSetArgs(s, shotReportCommand(job));
  s << "\n"
    << "else\n"
    << "  task=\"chunk ${SLURM_ARRAY_TASK_ID:-?} of 0-" << last << "\"\n";
  writeSetArgs(s, chunkBakeCommand(job, "env"));
  if (job.perChunkReport) {
    s << " '--report' "
      << shellQuote(job.outputFolder + "/" + sequenceStem(job.outputPattern) + ".chunk")
      << "\"$SLURM_ARRAY_TASK_ID\"'.report.json'";
  }
  s << "\n"
    << "fi\n";
  writeSlurmRunTail(s, "bake",
                    "# The bake runs in the background so that this shell can pass SIGTERM "
                    "(scancel, time\n"
                    "# limit, preemption) and SIGINT on to it; the bake finishes the frames in "
                    "hand, removes\n"
                    "# its temporary files and exits 7. The task's exit code is always the "
                    "bake's.\n");
  return s.str();
}

std::string slurmSimulateScript(const SimulateFarmJob& job, const std::string& logPattern,
                                const std::string& partition) {
  const std::string windows = std::to_string(job.windows);
  std::ostringstream s;
  s << "#!/bin/bash\n"
    << "# Written by drivenshape " << kVersion << " (`drivenshape farm slurm simulate`): the "
    << windows << " windows of the\n"
    << "# simulation plan of frames " << job.firstFrame << "-" << job.lastFrame
    << " of the bake's report, one array task each.\n"
    << "# Array index N is a window number (1 = the first): task N runs `drivenshape simulate\n"
    << "# ... --window N`, which keeps a window a run before left complete; resubmit failed\n"
    << "# windows with\n"
    << "#   sbatch --array=N,M <this file>\n"
    << "# With the argument `splice` (after the windows: sbatch --dependency=afterok:JOB\n"
    << "# --array=0 <this file> splice) it splices every window into the output\n"
    << "# (`drivenshape simulate ... --splice-only`).\n";
  writeSbatchLines(s, job.name, "1-" + windows, logPattern, partition, job.timeLimit, job.cpus,
                   job.memoryMb);
  s << "set -u\n"
    << "\n"
    << "mkdir -p " << shellQuote(job.outputFolder) << "\n"
    << "if [ \"${1:-}\" = splice ]; then\n"
    << "  task=\"the splice\"\n";
  writeSetArgs(s, simulateSpliceCommand(job));
  s << "\n"
    << "else\n"
    << "  task=\"window ${SLURM_ARRAY_TASK_ID:-?} of 1-" << windows << "\"\n";
  std::vector<std::string> words = simulateWindowCommand(job, "");
  words.pop_back();  // the window: the array index
  writeSetArgs(s, words);
  s << " \"$SLURM_ARRAY_TASK_ID\"\n"
    << "fi\n";
  writeSlurmRunTail(s, "simulate",
                    "# drivenshape simulate runs in the background so that this shell can pass "
                    "SIGTERM and\n"
                    "# SIGINT on to it. The task's exit code is always its own.\n");
  return s.str();
}

std::vector<std::string> slurmReportOptions(const FarmJob& job, const std::string& arrayJob) {
  return {"--dependency=afterok:" + arrayJob, "--array=0", "--job-name=" + job.name + "_report"};
}

std::vector<std::string> slurmSpliceOptions(const SimulateFarmJob& job,
                                            const std::string& arrayJob) {
  return {"--dependency=afterok:" + arrayJob, "--array=0", "--job-name=" + job.name + "_splice"};
}

/// Runs `sbatch --parsable OPTIONS SCRIPT ARGS` and returns the job id it prints.
std::string submitToSlurm(const std::string& script, const std::vector<std::string>& options,
                          const std::vector<std::string>& scriptArgs) {
  std::string command = "sbatch --parsable";
  for (const std::string& option : options) {
    command += " " + shellQuote(option);
  }
  command += " " + shellQuote(script);
  for (const std::string& arg : scriptArgs) {
    command += " " + shellQuote(arg);
  }
  command += " 2>&1";
  std::FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) {
    DS_THROW(kOutput, "cannot run sbatch; the job script is at '", script,
             "', submit it by hand with `sbatch ", script, "`");
  }
  std::string output;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) {
    output += buffer;
  }
  const int status = ::pclose(pipe);
  while (!output.empty() && std::isspace(static_cast<unsigned char>(output.back()))) {
    output.pop_back();
  }
  const int code = (status != -1 && WIFEXITED(status)) ? WEXITSTATUS(status) : -1;
  if (code != 0) {
    DS_THROW(kOutput, "sbatch failed (exit ", code, code == 127 ? ", is Slurm installed?" : "",
             "): ", output, "; the job script is at '", script, "'");
  }
  // --parsable prints "jobid" or "jobid;cluster"; the id is the last line's first field.
  std::string id = output.substr(output.find_last_of('\n') + 1);
  id = id.substr(0, id.find(';'));
  if (id.empty() || !std::all_of(id.begin(), id.end(), ::isdigit)) {
    DS_THROW(kOutput, "sbatch printed no job id: '", output, "'; the job script is at '", script,
             "'");
  }
  return id;
}

// ---- Open Job Description ------------------------------------------------------------------

namespace {

// Limits of the 2023-09 template schema (openjd-model), in characters (code points).
constexpr std::size_t kOpenJdMaxName = 512;
constexpr std::size_t kOpenJdMaxDescription = 2048;
constexpr std::size_t kOpenJdMaxParameterValue = 1024;
constexpr std::size_t kOpenJdMaxVariableValue = 2048;
constexpr int kOpenJdMaxNotifySeconds = 600;

/// Characters of UTF-8 `text`, as Open Job Description counts lengths.
std::size_t characterCount(const std::string& text) {
  return static_cast<std::size_t>(std::count_if(text.begin(), text.end(), [](char c) {
    return (static_cast<unsigned char>(c) & 0xC0u) != 0x80u;
  }));
}

[[noreturn]] void failTemplateCheck(const std::string& where, const std::string& why) {
  DS_THROW(kInternal, "the Open Job Description template would fail `openjd check`: ", where, " ",
           why, "; please report this with the command line");
}

/// Every string and key under `value` is UTF-8.
void checkTemplateUtf8(const nlohmann::ordered_json& value, const std::string& where) {
  if (value.is_string() && !isUtf8(value.get_ref<const std::string&>())) {
    failTemplateCheck(where, "is not valid UTF-8");
  }
  if (value.is_object()) {
    for (const auto& item : value.items()) {
      if (!isUtf8(item.key())) {
        failTemplateCheck(where, "has a key that is not valid UTF-8");
      }
      checkTemplateUtf8(item.value(), where + "." + item.key());
    }
  } else if (value.is_array()) {
    for (std::size_t i = 0; i < value.size(); ++i) {
      checkTemplateUtf8(value[i], where + "[" + std::to_string(i) + "]");
    }
  }
}

/// A string of minLength..maxLength characters with no control character but
/// `allowedControls` (any, when null); returns it.
std::string templateText(const nlohmann::ordered_json& value, const std::string& where,
                         std::size_t minLength, std::size_t maxLength,
                         const char* allowedControls) {
  if (!value.is_string()) {
    failTemplateCheck(where, "is not a string");
  }
  const std::string& content = value.get_ref<const std::string&>();
  const std::size_t length = characterCount(content);
  if (length < minLength || length > maxLength) {
    failTemplateCheck(where, "has " + std::to_string(length) + " characters, not " +
                                 std::to_string(minLength) + " to " + std::to_string(maxLength));
  }
  if (allowedControls != nullptr && hasControlCharacter(content, allowedControls)) {
    failTemplateCheck(where, "holds a control character");
  }
  return content;
}

/// A format string whose expressions are all `symbols`. OpenJD finds the next "{{" and the
/// next "}}" and parses what lies between as an expression.
void checkFormatString(const nlohmann::ordered_json& value, const std::string& where,
                       const std::set<std::string>& symbols, std::size_t minLength,
                       std::size_t maxLength, const char* allowedControls) {
  const std::string content = templateText(value, where, minLength, maxLength, allowedControls);
  std::size_t at = 0;
  for (;;) {
    const std::size_t open = content.find("{{", at);
    const std::size_t close = content.find("}}", at);
    if (open == std::string::npos && close == std::string::npos) {
      break;
    }
    if (open == std::string::npos || close < open) {
      failTemplateCheck(where, "'" + content + "' has '}}' without '{{'");
    }
    std::string expression = content.substr(open + 2, close - open - 2);
    expression.erase(0, expression.find_first_not_of(' '));
    expression.erase(expression.find_last_not_of(' ') + 1);
    if (symbols.count(expression) == 0) {
      failTemplateCheck(where,
                        "'" + content + "' refers to '" + expression + "', which is not defined");
    }
    at = close + 2;
  }
}

void checkTemplateDescription(const nlohmann::ordered_json& owner, const std::string& where) {
  if (owner.contains("description")) {
    templateText(owner.at("description"), where + ".description", 1, kOpenJdMaxDescription,
                 "\r\n\t");
  }
}

/// A step: its environments' variables, its command and arguments (which may also use the
/// step's task parameters and the session folder), its notify period.
void checkTemplateStep(const nlohmann::ordered_json& step,
                       const std::set<std::string>& jobSymbols) {
  using json = nlohmann::ordered_json;
  const std::string where = "step " + step.at("name").get<std::string>();
  checkTemplateDescription(step, where);
  std::set<std::string> symbols = jobSymbols;
  symbols.insert("Session.WorkingDirectory");
  if (step.contains("parameterSpace")) {  // a step without one runs one task
    for (const json& parameter : step.at("parameterSpace").at("taskParameterDefinitions")) {
      symbols.insert("Task.Param." + parameter.at("name").get<std::string>());
    }
  }
  for (const json& environment : step.at("stepEnvironments")) {
    checkTemplateDescription(environment, where + " environment");
    for (const auto& variable : environment.at("variables").items()) {
      checkFormatString(variable.value(), where + " variable " + variable.key(), symbols, 0,
                        kOpenJdMaxVariableValue, "");
    }
  }
  const json& onRun = step.at("script").at("actions").at("onRun");
  checkFormatString(onRun.at("command"), where + " command", symbols, 1, SIZE_MAX, "");
  for (std::size_t i = 0; i < onRun.at("args").size(); ++i) {
    checkFormatString(onRun.at("args")[i], where + " argument " + std::to_string(i + 1), symbols, 0,
                      SIZE_MAX, "\r\n");
  }
  const int notify = onRun.at("cancelation").at("notifyPeriodInSeconds").get<int>();
  if (notify < 1 || notify > kOpenJdMaxNotifySeconds) {
    failTemplateCheck(where,
                      "notifyPeriodInSeconds " + std::to_string(notify) + " is outside 1..600");
  }
}

/// A step's command arguments: `words` (chunkBakeCommand or shotReportCommand) on the job's
/// path parameters, and the report `reportName` in {{Param.ReportFolder}} (when the job names
/// the reports: not with a --report of --extra-args).
nlohmann::ordered_json templateBakeArguments(const FarmJob& job,
                                             const std::vector<std::string>& words,
                                             const std::string& reportName) {
  using json = nlohmann::ordered_json;
  json args = json::array();
  for (const std::string& word : words) {
    args.push_back(word);
  }
  // The paths are job parameters (so a render manager can path-map them); the command uses
  // the parameters, never the literal defaults.
  args.erase(args.begin());
  args[2] = "{{Param.Database}}";
  args[4] = "{{Param.DriverCache}}";
  args[8] = "{{Param.OutputPattern}}";
  if (job.perChunkReport) {
    args.push_back("--report");
    args.push_back("{{Param.ReportFolder}}/" + reportName);
  }
  return args;
}

/// A step running `args`: the PoCL cache in the session folder, the host needs.
nlohmann::ordered_json templateStep(int cpus, int memoryMb, const char* name,
                                    const std::string& description,
                                    const nlohmann::ordered_json& args, long timeoutSeconds,
                                    int notifySeconds) {
  using json = nlohmann::ordered_json;
  json onRun{{"command", "{{Param.DrivenshapeBinary}}"},
             {"args", args},
             {"cancelation",
              {{"mode", "NOTIFY_THEN_TERMINATE"}, {"notifyPeriodInSeconds", notifySeconds}}}};
  if (timeoutSeconds > 0) {
    onRun["timeout"] = timeoutSeconds;
  }
  json step{{"name", name},
            {"description", description},
            {"stepEnvironments",
             json::array({{{"name", std::string("Drivenshape") + name + "Env"},
                           {"description", "PoCL kernel cache in the session's own folder"},
                           {"variables",
                            {{"POCL_CACHE_DIR", "{{Session.WorkingDirectory}}/pocl-cache"}}}}})},
            {"script", {{"actions", {{"onRun", onRun}}}}}};
  if (cpus > 0 || memoryMb > 0) {
    json amounts = json::array();
    if (cpus > 0) {
      amounts.push_back({{"name", "amount.worker.vcpu"}, {"min", cpus}});
    }
    if (memoryMb > 0) {
      amounts.push_back({{"name", "amount.worker.memory"}, {"min", memoryMb}});
    }
    step["hostRequirements"] = {{"amounts", amounts}};
  }
  return step;
}

/// The steps: Bake, a task per chunk; Report, after every chunk, the shot's report.
nlohmann::ordered_json templateSteps(const FarmJob& job, long timeoutSeconds, int notifySeconds) {
  using json = nlohmann::ordered_json;
  const std::string stem = sequenceStem(job.outputPattern);
  json bake = templateStep(job.cpus, job.memoryMb, "Bake",
                           "One task per chunk of " + std::to_string(job.chunkSize) +
                               " frames: task Chunk=I bakes frames [I*N, (I+1)*N) of " +
                               job.framesText + ", keeping finished frames (--skip-existing).",
                           templateBakeArguments(job, chunkBakeCommand(job, "{{Task.Param.Chunk}}"),
                                                 stem + ".chunk{{Task.Param.Chunk}}.report.json"),
                           timeoutSeconds, notifySeconds);
  bake["parameterSpace"] = {{"taskParameterDefinitions",
                             json::array({{{"name", "Chunk"},
                                           {"type", "INT"},
                                           {"range", "0-" + std::to_string(job.chunks - 1)}}})}};
  json report =
      templateStep(job.cpus, job.memoryMb, "Report",
                   "After every chunk: the shot's report from the records its frames "
                   "carry, every frame checked (--skip-existing).",
                   templateBakeArguments(job, shotReportCommand(job), stem + ".report.json"),
                   timeoutSeconds, notifySeconds);
  report["dependencies"] = json::array({{{"dependsOn", "Bake"}}});
  return json::array({bake, report});
}

/// A simulate step's arguments: `words` (simulateWindowCommand or simulateSpliceCommand) on the
/// job's parameters.
nlohmann::ordered_json templateSimulateArguments(const SimulateFarmJob& job,
                                                 const std::vector<std::string>& words) {
  nlohmann::ordered_json args = nlohmann::ordered_json::array();
  for (std::size_t i = 1; i < words.size(); ++i) {
    args.push_back(words[i]);
  }
  args[2] = "{{Param.Blend}}";
  args[6] = "{{Param.BakeReport}}";
  args[8] = "{{Param.BakePattern}}";
  args[10] = "{{Param.OutputPattern}}";
  for (std::size_t i = 11; i + 1 < args.size(); ++i) {
    if (!job.blender.empty() && args[i] == "--blender") {
      args[i + 1] = "{{Param.Blender}}";
    }
  }
  return args;
}

/// The steps of a simulate job: Simulate, a task per window; Splice, after every window.
nlohmann::ordered_json templateSimulateSteps(const SimulateFarmJob& job, long timeoutSeconds,
                                             int notifySeconds) {
  using json = nlohmann::ordered_json;
  const std::string windows = std::to_string(job.windows);
  json simulate = templateStep(
      job.cpus, job.memoryMb, "Simulate",
      "One task per window of the simulation plan: task Window=N simulates window N of " + windows +
          " in Blender, keeping a window a run before left complete (--window N).",
      templateSimulateArguments(job, simulateWindowCommand(job, "{{Task.Param.Window}}")),
      timeoutSeconds, notifySeconds);
  simulate["parameterSpace"] = {
      {"taskParameterDefinitions",
       json::array({{{"name", "Window"}, {"type", "INT"}, {"range", "1-" + windows}}})}};
  json splice = templateStep(job.cpus, job.memoryMb, "Splice",
                             "After every window: the windows spliced into the bake, every frame "
                             "of the report written (--splice-only).",
                             templateSimulateArguments(job, simulateSpliceCommand(job)),
                             timeoutSeconds, notifySeconds);
  splice["dependencies"] = json::array({{{"dependsOn", "Simulate"}}});
  return json::array({simulate, splice});
}

/// A PATH job parameter holding `value`; its default is `value` relative to `templateDir` when
/// it lies inside it. The absolute value goes into `values`.
nlohmann::ordered_json pathParameter(const char* name, const std::string& value,
                                     const char* objectType, const char* flow,
                                     const char* description, const std::string& templateDir,
                                     nlohmann::ordered_json& values) {
  nlohmann::ordered_json parameter{{"name", name}, {"type", "PATH"}, {"dataFlow", flow}};
  if (objectType != nullptr) {
    parameter["objectType"] = objectType;
  }
  const fs::path relative = fs::path(value).lexically_relative(templateDir);
  if (!relative.empty() && *relative.begin() != "..") {
    parameter["default"] = relative.string();
  }
  parameter["description"] = description;
  values[name] = value;
  return parameter;
}

/// A mapping key: plain when it is an identifier, else a JSON (double-quoted) string.
std::string yamlKey(const std::string& key) {
  const bool plain =
      !key.empty() && (std::isalpha(static_cast<unsigned char>(key[0])) || key[0] == '_') &&
      std::all_of(key.begin(), key.end(),
                  [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
  return plain ? key : jsonText(nlohmann::json(key));
}

bool hasSuffix(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

void checkCancelGrace(int seconds) {
  if (seconds > kOpenJdMaxNotifySeconds) {
    DS_THROW(kUsage, "--cancel-grace ", seconds, " is outside 1..", kOpenJdMaxNotifySeconds,
             " seconds, the notify period Open Job Description allows");
  }
}

/// A value of the command line that lands in a format string of the template (the job name,
/// an argument of the bake): Open Job Description reads `{{`...`}}` there as an expression and
/// has no escape for the braces, and allows no control characters but `allowedControls`.
/// Refused with Error(kUsage) naming `who`.
void checkTemplateText(const std::string& who, const std::string& text,
                       const std::string& allowedControls) {
  if (!isUtf8(text)) {
    DS_THROW(kUsage, who, " is not valid UTF-8, which an Open Job Description template holds");
  }
  if (text.find("{{") != std::string::npos || text.find("}}") != std::string::npos) {
    DS_THROW(kUsage, who,
             " holds '{{' or '}}', which Open Job Description reads as an expression (it has "
             "no escape for them); remove them");
  }
  if (hasControlCharacter(text, allowedControls)) {
    DS_THROW(kUsage, who,
             " holds a control character, which Open Job Description does not "
             "allow there");
  }
}

/// A path that becomes a job parameter value: UTF-8 (the template and its values are UTF-8
/// text, other bytes would change the path) of at most kOpenJdMaxParameterValue characters.
void checkTemplatePath(const std::string& who, const std::string& path) {
  if (!isUtf8(path)) {
    DS_THROW(kUsage, who,
             " is not valid UTF-8, which an Open Job Description template holds; "
             "rename it");
  }
  if (characterCount(path) > kOpenJdMaxParameterValue) {
    DS_THROW(kUsage, who, " is ", characterCount(path),
             " characters long as an absolute path; "
             "an Open Job Description job parameter holds at most ",
             kOpenJdMaxParameterValue);
  }
}

/// The template's own check before it is written: what openjd-model (`openjd check`) refuses
/// in the fields this command writes. Every string UTF-8; the format strings (name, command,
/// arguments, environment variables) with balanced `{{ }}` around only the expressions this
/// command writes (the job's parameters, the step's task parameters, the session folder) and
/// no control characters (arguments may break lines); names, descriptions and parameter
/// defaults within their lengths; the notify period within 1..600 s. The checks of the options
/// come first and name the option, so a failure here is a bug: Error(kInternal).
void checkJobTemplate(const nlohmann::ordered_json& jobTemplate) {
  using json = nlohmann::ordered_json;
  checkTemplateUtf8(jobTemplate, "template");
  std::set<std::string> jobSymbols;
  for (const json& parameter : jobTemplate.at("parameterDefinitions")) {
    const std::string name = parameter.at("name").get<std::string>();
    jobSymbols.insert("Param." + name);
    checkTemplateDescription(parameter, "parameter " + name);
    if (parameter.contains("default")) {
      templateText(parameter.at("default"), "parameter " + name + ".default", 0,
                   kOpenJdMaxParameterValue, nullptr);
    }
  }
  checkFormatString(jobTemplate.at("name"), "the job name", jobSymbols, 1, kOpenJdMaxName, "");
  checkTemplateDescription(jobTemplate, "the job");
  for (const json& step : jobTemplate.at("steps")) {
    checkTemplateStep(step, jobSymbols);
  }
}

/// The template. PATH parameters (path-mapped by render managers) hold the data. The spec
/// only allows relative defaults that stay inside the template's folder `templateDir` (they are
/// joined to it when a job is created), so a path gets a default only there; every path's
/// absolute value also goes into `values`, the job parameter values file written beside the
/// template. The executable is a STRING: it is where drivenshape is installed on the workers,
/// not data to map.
nlohmann::ordered_json openJobTemplate(const FarmJob& job, const std::string& templateDir,
                                       long timeoutSeconds, int notifySeconds,
                                       nlohmann::ordered_json& values) {
  using json = nlohmann::ordered_json;
  return json{
      {"specificationVersion", "jobtemplate-2023-09"},
      {"name", job.name},
      {"description", "drivenshape " + std::string(kVersion) + " bake of " +
                          std::to_string(job.frameCount) + " frames (" + job.framesText + ") in " +
                          std::to_string(job.chunks) + " chunks"},
      {"parameterDefinitions",
       json::array({{{"name", "DrivenshapeBinary"},
                     {"type", "STRING"},
                     {"default", job.binary},
                     {"description", "the drivenshape executable on the workers"}},
                    pathParameter("Database", job.database, "FILE", "IN",
                                  "database from `drivenshape db build`", templateDir, values),
                    pathParameter("DriverCache", job.driver, nullptr, "IN",
                                  "shot driver cache (.pc2 or name.####.exr)", templateDir, values),
                    pathParameter("OutputPattern", job.outputPattern, nullptr, "OUT",
                                  "output EXR sequence", templateDir, values),
                    pathParameter("ReportFolder", job.outputFolder, "DIRECTORY", "OUT",
                                  "folder of the JSON reports: each chunk's and the shot's",
                                  templateDir, values)})},
      {"steps", templateSteps(job, timeoutSeconds, notifySeconds)}};
}

nlohmann::ordered_json openJobSimulateTemplate(const SimulateFarmJob& job,
                                               const std::string& templateDir, long timeoutSeconds,
                                               int notifySeconds, nlohmann::ordered_json& values) {
  using json = nlohmann::ordered_json;
  json parameters = json::array({{{"name", "DrivenshapeBinary"},
                                  {"type", "STRING"},
                                  {"default", job.binary},
                                  {"description", "the drivenshape executable on the workers"}}});
  if (!job.blender.empty()) {
    parameters.push_back({{"name", "Blender"},
                          {"type", "STRING"},
                          {"default", job.blender},
                          {"description", "the Blender executable on the workers"}});
  }
  for (json parameter :
       {pathParameter("Blend", job.blend, "FILE", "IN", "the shot's scene with the garment's cloth",
                      templateDir, values),
        pathParameter("BakeReport", job.report, "FILE", "IN", "the bake's report", templateDir,
                      values),
        pathParameter("BakePattern", job.bake, nullptr, "IN", "the bake's EXR sequence",
                      templateDir, values),
        pathParameter("OutputPattern", job.outputPattern, nullptr, "OUT",
                      "output EXR sequence (its plan, windows and report beside it)", templateDir,
                      values)}) {
    parameters.push_back(parameter);
  }
  return json{{"specificationVersion", "jobtemplate-2023-09"},
              {"name", job.name},
              {"description", "drivenshape " + std::string(kVersion) + " simulation of the " +
                                  std::to_string(job.windows) + " windows of frames " +
                                  std::to_string(job.firstFrame) + "-" +
                                  std::to_string(job.lastFrame) + " and their splice"},
              {"parameterDefinitions", parameters},
              {"steps", templateSimulateSteps(job, timeoutSeconds, notifySeconds)}};
}

/// Block-style YAML of a JSON value. Strings are written as JSON strings, which YAML reads as
/// double-quoted scalars with the same escapes, so no value can change meaning.
void writeYaml(std::ostream& out, const nlohmann::ordered_json& value, int indent,
               bool inlineFirst) {
  const std::string pad(static_cast<std::size_t>(indent), ' ');
  if (value.is_object()) {
    bool first = true;
    for (const auto& item : value.items()) {
      out << ((first && inlineFirst) ? std::string() : pad) << yamlKey(item.key()) << ":";
      const auto& child = item.value();
      if ((child.is_object() || child.is_array()) && !child.empty()) {
        out << "\n";
        writeYaml(out, child, indent + 2, false);
      } else {
        out << " " << jsonText(child) << "\n";
      }
      first = false;
    }
  } else if (value.is_array()) {
    for (const auto& child : value) {
      out << pad << "- ";
      if ((child.is_object() || child.is_array()) && !child.empty()) {
        writeYaml(out, child, indent + 2, true);
      } else {
        out << jsonText(child) << "\n";
      }
    }
  } else {
    out << pad << jsonText(value) << "\n";
  }
}

std::string openJobTemplateText(const nlohmann::ordered_json& jobTemplate,
                                const std::string& jobFile) {
  if (hasSuffix(jobFile, ".yaml") || hasSuffix(jobFile, ".yml")) {
    std::ostringstream yaml;
    yaml << "# Open Job Description job template written by drivenshape " << kVersion << "\n";
    writeYaml(yaml, jobTemplate, 0, false);
    return yaml.str();
  }
  return jsonText(jobTemplate, 2) + "\n";
}

/// shot.template.json -> shot.template.params.json (also for .yaml/.yml and no extension).
std::string openJobParametersPath(const std::string& jobFile) {
  std::string stem = jobFile;
  for (const char* extension : {".json", ".yaml", ".yml"}) {
    if (hasSuffix(stem, extension)) {
      stem.resize(stem.size() - std::string(extension).size());
      break;
    }
  }
  return stem + ".params.json";
}

}  // namespace drivenshape
