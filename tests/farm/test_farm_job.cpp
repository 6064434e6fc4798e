// SPDX-License-Identifier: Apache-2.0
// The farm job model of the library (src/shot/farm_job.h), without a command line: the chunk
// plan, the Slurm script's bake command, the Open Job Description template and its check; the
// simulate job's tasks from the library's plan.
#include "farm_job.h"

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include <drivenshape/coverage_check.h>
#include <drivenshape/frames.h>
#include <drivenshape/simulation.h>

#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// A job of frames 1001-1100 in chunks of 10, as `drivenshape farm` builds it.
FarmJob sampleJob() {
  FarmJob job;
  job.binary = "/opt/drivenshape/bin/drivenshape";
  job.database = "/shows/x/cloth db.dsdb";
  job.driver = "/shows/x/shot.pc2";
  job.frames = "1001-1100";
  job.outputPattern = "/shows/x/out/cloth.####.exr";
  job.outputFolder = "/shows/x/out";
  job.chunkSize = 10;
  planFarmChunks(job, parseFrameRange(job.frames));
  job.name = defaultFarmJobName(job.outputPattern);
  return job;
}

TEST(FarmJob, ChunkPlan) {
  const FarmJob job = sampleJob();
  EXPECT_EQ(job.frameCount, 100);
  EXPECT_EQ(job.chunks, 10);
  EXPECT_EQ(job.framesText, "1001-1100");
  EXPECT_EQ(job.name, "ds_cloth");
  FarmJob odd = job;
  odd.chunkSize = 30;
  planFarmChunks(odd, parseFrameRange(odd.frames));
  EXPECT_EQ(odd.chunks, 4);
}

TEST(FarmJob, SlurmScriptRunsTheChunksBake) {
  FarmJob job = sampleJob();
  setFarmExtraArgs(job, "--batch 16 'a b'");
  const std::string script = slurmScript(job, slurmLogPattern("/logs", job.name, "logs"), "");
  std::string command;
  for (const std::string& word : chunkBakeCommand(job, "env")) {
    command += (command.empty() ? "" : " ") + shellQuote(word);
  }
  EXPECT_NE(script.find(command + " '--report' "), std::string::npos) << script;
  EXPECT_NE(command.find("'--chunk-index' 'env' '--skip-existing' '--batch' '16' 'a b'"),
            std::string::npos)
      << command;
  EXPECT_NE(script.find("#SBATCH --array=0-9\n"), std::string::npos);
  EXPECT_NE(script.find("#SBATCH --output=/logs/ds_cloth_%A_%a.log\n"), std::string::npos);
}

TEST(FarmJob, ExtraArgs) {
  FarmJob job = sampleJob();
  setFarmExtraArgs(job, "--report \"/r/a b.json\"");
  EXPECT_EQ(job.extraArgs, (std::vector<std::string>{"--report", "/r/a b.json"}));
  EXPECT_FALSE(job.perChunkReport);
  expectThrows([&] { setFarmExtraArgs(job, "--chunk-index=3"); }, ErrorCode::kUsage,
               "must not hold --chunk-index");
  expectThrows([&] { setFarmExtraArgs(job, "'open"); }, ErrorCode::kUsage, "unclosed");
}

TEST(FarmJob, TimeLimits) {
  EXPECT_EQ(parseTimeLimit("90"), 90 * 60);
  EXPECT_EQ(parseTimeLimit("01:30"), 90);
  EXPECT_EQ(parseTimeLimit("02:00:00"), 7200);
  EXPECT_EQ(parseTimeLimit("1-02"), 26 * 3600);
  expectThrows([] { parseTimeLimit("1:"); }, ErrorCode::kUsage, "--time '1:'");
  expectThrows([] { parseTimeLimit("0"); }, ErrorCode::kUsage, "not a time limit");
}

TEST(FarmJob, OpenJobTemplatePassesItsCheck) {
  const FarmJob job = sampleJob();
  nlohmann::ordered_json values = nlohmann::ordered_json::object();
  const nlohmann::ordered_json jobTemplate = openJobTemplate(job, "/shows/x", 3600, 120, values);
  checkJobTemplate(jobTemplate);
  EXPECT_EQ(jobTemplate.at("name"), "ds_cloth");
  EXPECT_EQ(values.at("Database"), job.database);
  const auto& onRun = jobTemplate.at("steps")[0].at("script").at("actions").at("onRun");
  EXPECT_EQ(onRun.at("timeout"), 3600);
  EXPECT_EQ(onRun.at("args")[12], "{{Task.Param.Chunk}}");
  const std::string yaml = openJobTemplateText(jobTemplate, "/shows/x/job.yaml");
  EXPECT_EQ(yaml.rfind("# Open Job Description job template", 0), 0u);
  EXPECT_EQ(openJobTemplateText(jobTemplate, "/shows/x/job.json").front(), '{');
  EXPECT_EQ(openJobParametersPath("/shows/x/job.template.yml"),
            "/shows/x/job.template.params.json");
  EXPECT_EQ(openJobParametersPath("/shows/x/job"), "/shows/x/job.params.json");
}

TEST(FarmJob, TemplateCheckRefusesAnUnknownExpression) {
  nlohmann::ordered_json values = nlohmann::ordered_json::object();
  nlohmann::ordered_json jobTemplate = openJobTemplate(sampleJob(), "/", 0, 120, values);
  jobTemplate["name"] = "{{Param.Nothing}}";
  expectThrows([&] { checkJobTemplate(jobTemplate); }, ErrorCode::kInternal,
               "refers to 'Param.Nothing'");
}

/// The plan of frames 1-40 with `flagged` flagged, warm-up 3, merge gap 2, goal 0.5, the rest
/// the defaults.
SimulationPlan samplePlan(const std::vector<int>& flagged) {
  BakeReportCoverage report;
  report.source = "/shows/x/bake.report.json";
  for (int f = 1; f <= 40; ++f) {
    const bool isFlagged = std::find(flagged.begin(), flagged.end(), f) != flagged.end();
    report.predicted.push_back({f, isFlagged ? 0.05 : 0.01, isFlagged});
  }
  SimulationOptions settings;
  settings.warmup = 3;
  settings.mergeGap = 2;
  settings.goalStrength = 0.5;
  return planSimulation(report, settings);
}

SimulateFarmJob sampleSimulateJob(const SimulationPlan& plan) {
  SimulateFarmJob job;
  job.binary = "/opt/drivenshape/bin/drivenshape";
  job.blend = "/shows/x/shot.blend";
  job.object = "pants";
  job.report = plan.report;
  job.bake = "/shows/x/bake/c.####.exr";
  job.outputPattern = "/shows/x/final/c.####.exr";
  job.outputFolder = "/shows/x/final";
  job.name = "ds_c_simulate";
  setSimulateFarmPlan(job, plan);
  return job;
}

TEST(FarmJob, SimulateJobHasATaskPerWindowOfThePlan) {
  // Runs 5-6, 9 (merged: gap 2) and 30: two windows.
  const SimulationPlan plan = samplePlan({5, 6, 9, 30});
  ASSERT_EQ(plan.windows.size(), 2u);
  const SimulateFarmJob job = sampleSimulateJob(plan);
  EXPECT_EQ(job.windows, 2);
  const std::vector<std::string> settings = {"--warmup",        "3",   "--merge-gap", "2",
                                             "--goal-strength", "0.5", "--seam",      "4",
                                             "--carry",         "10"};
  EXPECT_EQ(job.settingArgs, settings);
  std::vector<std::string> window = {job.binary, "simulate", "--blend",  job.blend,
                                     "--object", "pants",    "--report", job.report,
                                     "--bake",   job.bake,   "-o",       job.outputPattern};
  window.insert(window.end(), settings.begin(), settings.end());
  std::vector<std::string> splice = window;
  window.insert(window.end(), {"--window", "2"});
  splice.emplace_back("--splice-only");
  EXPECT_EQ(simulateWindowCommand(job, "2"), window);
  EXPECT_EQ(simulateSpliceCommand(job), splice);
  SimulationOptions fromStart;
  fromStart.fromStart = true;
  EXPECT_EQ(simulationSettingArgs(fromStart).back(), "--from-start");
  expectThrows([&] { sampleSimulateJob(samplePlan({})); }, ErrorCode::kInput,
               "flags no frame of 1-40");
}

TEST(FarmJob, SimulateSlurmScriptAndTemplate) {
  SimulateFarmJob job = sampleSimulateJob(samplePlan({5, 6, 9, 30}));
  job.blender = "/opt/blender/blender";
  const std::string script =
      slurmSimulateScript(job, slurmLogPattern("/logs", job.name, "logs"), "");
  EXPECT_NE(script.find("#SBATCH --array=1-2\n"), std::string::npos) << script;
  EXPECT_NE(script.find("'--blender' '/opt/blender/blender' '--window' \"$SLURM_ARRAY_TASK_ID\"\n"),
            std::string::npos)
      << script;
  EXPECT_NE(script.find("'--carry' '10' '--blender' '/opt/blender/blender' '--splice-only'\n"),
            std::string::npos)
      << script;
  EXPECT_EQ(slurmSpliceOptions(job, "17"),
            (std::vector<std::string>{"--dependency=afterok:17", "--array=0",
                                      "--job-name=ds_c_simulate_splice"}));
  nlohmann::ordered_json values = nlohmann::ordered_json::object();
  const nlohmann::ordered_json jobTemplate =
      openJobSimulateTemplate(job, "/shows/x", 0, 120, values);
  checkJobTemplate(jobTemplate);
  EXPECT_EQ(values.at("Blend"), job.blend);
  EXPECT_EQ(values.at("BakeReport"), job.report);
  const auto& steps = jobTemplate.at("steps");
  EXPECT_EQ(steps[0].at("parameterSpace").at("taskParameterDefinitions")[0].at("range"), "1-2");
  EXPECT_EQ(steps[1].at("dependencies")[0].at("dependsOn"), "Simulate");
  const auto& args = steps[0].at("script").at("actions").at("onRun").at("args");
  EXPECT_EQ(args[2], "{{Param.Blend}}");
  EXPECT_EQ(args[args.size() - 3], "{{Param.Blender}}");
  EXPECT_EQ(args.back(), "{{Task.Param.Window}}");
}

}  // namespace
}  // namespace drivenshape::testing
