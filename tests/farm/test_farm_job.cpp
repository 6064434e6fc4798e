// SPDX-License-Identifier: Apache-2.0
// The farm job model of the library (src/shot/farm_job.h), without a command line: the chunk
// plan, the Slurm script's bake command, the Open Job Description template and its check.
#include "farm_job.h"

#include <sstream>
#include <string>
#include <vector>

#include <drivenshape/frames.h>

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

}  // namespace
}  // namespace drivenshape::testing
