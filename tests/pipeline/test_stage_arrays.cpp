// SPDX-License-Identifier: Apache-2.0
// The arrays the pipeline's stages declare (src/pipeline/stage.h, executor.h): the built-in
// stages are wired (every array a stage reads is an input or an earlier stage's) and run within
// their declarations under many settings; an access a stage did not declare throws, naming the
// stage and the array; a wiring where a stage reads what no one wrote is refused.

#include <algorithm>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <drivenshape/database.h>
#include <drivenshape/device.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/layers.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/regions.h>

#include "executor.h"
#include "stage.h"
#include "test_support.h"

namespace drivenshape::pipeline {
namespace {

std::string data(const std::string& name) {
  return std::string(DS_TEST_DATA_DIR) + "/" + name;
}

/// A 10-shape database of the bundled sleeve sample with its pose model (the default weights
/// are the model's), built once.
const Database& sampleDatabase() {
  static const Database db = testing::buildSleeveDatabase(true);
  return db;
}

/// The message of what `call` throws as std::logic_error ("" when it throws nothing).
std::string logicError(const std::function<void()>& call) {
  try {
    call();
  } catch (const std::logic_error& error) {
    return error.what();
  }
  return "";
}

std::vector<std::string> names(const std::vector<StagePlan>& plan) {
  std::vector<std::string> out;
  for (const StagePlan& stage : plan) {
    out.push_back(stage.name);
  }
  return out;
}

/// The wiring rule, checked here on its own: every read is an input or written before.
void expectWired(const std::vector<StagePlan>& plan) {
  Arrays written = kInputArrays;
  for (const StagePlan& stage : plan) {
    for (const Array array : stage.reads.list()) {
      EXPECT_TRUE(written.has(array)) << stage.name << " reads " << arrayName(array);
    }
    written = written | stage.writes;
  }
  EXPECT_TRUE(written.has(Array::Cloth));
}

struct Case {
  const char* name;
  std::function<void(EvaluatorSettings&)> change;
  std::vector<std::string> stages;
  /// More about the declarations these settings give.
  std::function<void(const std::vector<StagePlan>&)> check = [](const std::vector<StagePlan>&) {};
};

void talk(EvaluatorSettings& s) {
  s.weightMode = WeightMode::kQp;
  s.align = AlignMode::kNone;
  s.blend = BlendMode::kWorld;
  s.resolve = false;
}

void bind(EvaluatorSettings& s) {
  s.weightMode = WeightMode::kBind;
  s.resolve = false;
}

void wind(EvaluatorSettings& s) {
  LayerOptions layers;
  layers.windAmplitude = 0.01;
  s.layers = loadLayers(layers, sampleDatabase().drivenMesh);
}

std::vector<Case> cases() {
  const Database& db = sampleDatabase();
  const auto reads = [](const StagePlan& stage, Array array) { return stage.reads.has(array); };
  // The cases below start from the defaults without the strain limit (the test turns it off
  // before each case's change): each adds one feature's stages.
  return {
      {"defaults",
       [](EvaluatorSettings& s) { s = EvaluatorSettings{}; },
       {"weights", "blend", "correct", "strain", "resolve", "settle", "audit"},
       [&](const std::vector<StagePlan>& plan) {
         // The resolution keeps the strain stage's answers; the settle stage the resolution's.
         EXPECT_TRUE(reads(plan[4], Array::AuditAnswered) && reads(plan[5], Array::AuditHits));
       }},
      {"strain limit without the resolution",
       [](EvaluatorSettings& s) {
         s = EvaluatorSettings{};
         s.resolve = false;
       },
       {"weights", "blend", "correct", "strain", "audit"}},
      {"no strain limit",
       [](EvaluatorSettings&) {},
       {"weights", "blend", "correct", "resolve", "audit"},
       [&](const std::vector<StagePlan>& plan) {
         // The audit keeps the resolution's hits for the points it proved clear.
         EXPECT_TRUE(reads(plan[4], Array::Moved) && reads(plan[4], Array::AuditHits));
         EXPECT_FALSE(reads(plan[4], Array::LayersApplied) || reads(plan[4], Array::Hits));
       }},
      {"weights qp",
       [](EvaluatorSettings& s) { s.weightMode = WeightMode::kQp; },
       {"align", "project", "weights", "blend", "correct", "resolve", "audit"},
       [&](const std::vector<StagePlan>& plan) {
         EXPECT_TRUE(reads(plan[2], Array::Projections) && plan[2].writes.has(Array::Solutions));
       }},
      {"talk",
       &talk,
       {"project", "weights", "blend", "correct", "audit", "audit"},
       [&](const std::vector<StagePlan>& plan) {
         EXPECT_TRUE(reads(plan[3], Array::BlendedDriver) && plan[3].writes.has(Array::Hits));
         EXPECT_TRUE(reads(plan[5], Array::Hits));
         EXPECT_FALSE(reads(plan[5], Array::Moved));
       }},
      {"bind",
       &bind,
       {"blend", "correct", "audit", "audit"},
       [&](const std::vector<StagePlan>& plan) { EXPECT_FALSE(reads(plan[0], Array::Weights)); }},
      {"bind with the resolution",
       [](EvaluatorSettings& s) { s.weightMode = WeightMode::kBind; },
       {"blend", "correct", "audit", "resolve", "audit"}},
      {"nearest",
       [](EvaluatorSettings& s) { s.weightMode = WeightMode::kNearest; },
       {"align", "weights", "blend", "correct", "resolve", "audit"},
       [&](const std::vector<StagePlan>& plan) {
         EXPECT_FALSE(reads(plan[1], Array::Projections));
       }},
      {"no correction",
       [](EvaluatorSettings& s) {
         s.weightMode = WeightMode::kQp;
         s.correct = false;
         s.blend = BlendMode::kWorld;
       },
       {"align", "project", "weights", "blend", "correct", "audit", "resolve", "audit"},
       [&](const std::vector<StagePlan>& plan) { EXPECT_TRUE(reads(plan[4], Array::Motions)); }},
      {"regions",
       [&db](EvaluatorSettings& s) {
         s.weightMode = WeightMode::kQp;
         s.regions = readRegions(data("golden/regions.json"), db.driverMesh, db.drivenMesh);
       },
       {"align", "project", "weights", "blend", "correct", "resolve", "audit"}},
      {"temporal bound",
       [](EvaluatorSettings& s) {
         s.weightMode = WeightMode::kQp;
         s.maxWeightChange = 0.05;
       },
       {"align", "project", "weights", "blend", "correct", "resolve", "audit"}},
      {"layers",
       &wind,
       {"weights", "blend", "correct", "resolve", "layers", "audit"},
       [&](const std::vector<StagePlan>& plan) {
         EXPECT_TRUE(reads(plan[4], Array::Shot) && plan[4].writes.has(Array::AuditHits));
         EXPECT_TRUE(reads(plan[5], Array::LayersApplied));
       }},
      {"layers, talk",
       [](EvaluatorSettings& s) {
         talk(s);
         wind(s);
       },
       {"project", "weights", "blend", "correct", "audit", "layers", "audit"}},
      {"layers, bind",
       [](EvaluatorSettings& s) {
         bind(s);
         wind(s);
       },
       {"blend", "correct", "audit", "layers", "audit"}},
      {"mix layer",
       [&db](EvaluatorSettings& s) {
         LayerOptions layers;
         layers.mixCache = data("sleeve/train.driven.pc2");
         layers.mixWeight = "group:sleeve";  // the driven OBJ's one group
         s.layers = loadLayers(layers, db.drivenMesh);
       },
       {"weights", "blend", "correct", "resolve", "layers", "audit"},
       [&](const std::vector<StagePlan>& plan) {
         EXPECT_FALSE(reads(plan[4], Array::Shot) || plan[4].writes.has(Array::AuditHits));
       }},
      {"audit off",
       [](EvaluatorSettings& s) { s.audit = false; },
       {"weights", "blend", "correct", "resolve"}},
      {"audit off, talk",
       [](EvaluatorSettings& s) {
         talk(s);
         s.audit = false;
       },
       {"project", "weights", "blend", "correct"}},
      {"audit off, layers",
       [](EvaluatorSettings& s) {
         wind(s);
         s.audit = false;
       },
       {"weights", "blend", "correct", "resolve", "layers"}},
  };
}

TEST(StageArrays, TheBuiltInStagesAreWiredAndRunWithinTheirDeclarations) {
  const Database& db = sampleDatabase();
  std::unique_ptr<Device> host = makeHostDevice();
  // Frames 1-4 of the test clip, the first as a warm-up frame (the shot is a view of the rest).
  const std::vector<int> frames = {1, 2, 3, 4};
  const std::vector<float> driver =
      readFrames(*openPointCache(data("sleeve/test.driver.pc2")), frames);
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.name);
    EvaluatorSettings settings;
    settings.strainLimit = 0.0;
    c.change(settings);
    Model model(db, settings, *host);
    const Executor executor(model);  // checks the wiring
    const std::vector<StagePlan> plan = executor.plan();
    ASSERT_EQ(names(plan), c.stages);
    expectWired(plan);
    c.check(plan);
    // Every access of every stage is checked against its declaration while it runs.
    Evaluator evaluator(db, settings, *host);
    std::vector<float> cloth(3 * 3 * static_cast<std::size_t>(db.drivenVertexCount()));
    std::vector<FrameRecord> records(3);
    EXPECT_EQ(logicError([&] {
                evaluator.evaluate(4, frames.data(), driver.data(), cloth.data(), records.data(),
                                   1);
                evaluator.evaluate(frames, driver);
              }),
              "");
  }
}

/// A stage of a test: its declaration and what it does.
class TestStage final : public Stage {
 public:
  TestStage(
      const char* name, Arrays reads, Arrays writes,
      std::function<void(Batch&)> body = [](Batch&) {})
      : mName(name), mBody(std::move(body)) {
    declare(reads, writes);
  }
  const char* name() const override { return mName; }
  void run(Batch& batch) override { mBody(batch); }

 private:
  const char* mName;
  std::function<void(Batch&)> mBody;
};

template <typename... Stages>
std::vector<std::unique_ptr<Stage>> stages(Stages... stages) {
  std::vector<std::unique_ptr<Stage>> out;
  (out.push_back(std::make_unique<TestStage>(std::move(stages))), ...);
  return out;
}

/// Runs `stages` on a batch of two frames of one driver and one cloth vertex.
void runTwoFrames(Device& device, std::vector<std::unique_ptr<Stage>> stages) {
  Executor executor(device, std::move(stages));
  const std::vector<int> frames = {7, 8};
  const std::vector<float> driver(6, 1.0f);
  std::vector<float> cloth(6, 0.0f);
  std::vector<FrameRecord> records(2);
  BatchInput input;
  input.solveCount = 2;
  input.frames = frames.data();
  input.driver = driver.data();
  input.cloth = cloth.data();
  input.records = records.data();
  input.driverValues = input.drivenValues = 3;
  StageSeconds seconds;
  executor.run(input, seconds);
}

TEST(StageArrays, AnUndeclaredAccessThrowsNamingTheStageAndTheArray) {
  std::unique_ptr<Device> host = makeHostDevice();
  const auto fill = [](Batch& batch) {
    batch.out<Array::Cloth>().write<float>();
    batch.out<Array::Driven>().resize<float>(6);
  };
  // Declared: the run goes through, reading what it writes and every input.
  EXPECT_EQ(logicError([&] {
              runTwoFrames(
                  *host, stages(TestStage("blend", {}, {Array::Driven, Array::Cloth}, fill),
                                TestStage("audit", {Array::Driven, Array::Frames}, {Array::Records},
                                          [](Batch& batch) {
                                            batch.in<Array::Driven>().read<float>();
                                            batch.out<Array::Records>()[1].resolved =
                                                batch.in<Array::Frames>()[1];
                                          })));
            }),
            "");
  // Read without a declaration.
  EXPECT_EQ(logicError([&] {
              runTwoFrames(*host, stages(TestStage("blend", {}, {Array::Driven, Array::Cloth},
                                                   [](Batch& batch) { batch.in<Array::Hits>(); })));
            }),
            "stage 'blend' reads 'hits' without declaring it");
  // Written when only declared read.
  EXPECT_EQ(logicError([&] {
              runTwoFrames(
                  *host,
                  stages(TestStage("blend", {}, {Array::Driven, Array::Cloth}, fill),
                         TestStage("resolve", {Array::Driven, Array::Cloth}, {}, [](Batch& batch) {
                           batch.in<Array::Cloth>();
                           batch.out<Array::Cloth>();
                         })));
            }),
            "stage 'resolve' writes 'cloth' without declaring it");
  // The input arrays too.
  EXPECT_EQ(logicError([&] {
              runTwoFrames(*host, stages(TestStage("align", {}, {Array::Cloth}, [](Batch& batch) {
                batch.in<Array::Driver>();
              })));
            }),
            "stage 'align' reads 'driver' without declaring it");
}

TEST(StageArrays, AWiringWhereAStageReadsWhatNoOneWroteIsRefused) {
  std::unique_ptr<Device> host = makeHostDevice();
  // The inputs need no writer.
  EXPECT_EQ(logicError([&] {
              Executor executor(*host, stages(TestStage("align", kInputArrays, {Array::Cloth})));
            }),
            "");
  EXPECT_EQ(logicError([&] {
              Executor executor(*host, stages(TestStage("correct", {Array::Shot}, {Array::Cloth}),
                                              TestStage("audit", {Array::Hits}, {Array::Records})));
            }),
            "stage 'audit' reads 'hits', which is not an input and no earlier stage writes");
  // Written, but only later.
  EXPECT_EQ(logicError([&] {
              Executor executor(*host, stages(TestStage("correct", {Array::Driven}, {Array::Cloth}),
                                              TestStage("blend", {}, {Array::Driven})));
            }),
            "stage 'correct' reads 'driven', which is not an input and no earlier stage writes");
  // The cloth is the result: some stage must write it.
  EXPECT_EQ(logicError(
                [&] { Executor executor(*host, stages(TestStage("blend", {}, {Array::Driven}))); }),
            "no stage writes 'cloth'");
}

TEST(StageArrays, EveryArrayHasItsOwnName) {
  std::vector<std::string> seen;
  for (int i = 0; i < kArrayCount; ++i) {
    const std::string name = arrayName(static_cast<Array>(i));
    EXPECT_NE(name, "?");
    EXPECT_EQ(std::count(seen.begin(), seen.end(), name), 0) << name;
    seen.push_back(name);
  }
  EXPECT_EQ((Arrays{Array::Cloth, Array::Frames}.names()), "frames, cloth");
}

}  // namespace
}  // namespace drivenshape::pipeline
