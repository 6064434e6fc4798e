// SPDX-License-Identifier: Apache-2.0
// The simulation plan (src/shot/simulation.cpp: what `drivenshape simulate --window N`,
// `--splice-only` and a farm's tasks read back): a plan that parses has its windows in frame
// order, apart and inside its frames, writes JSON that parses to the same plan, and splices a
// one-vertex shot over its frames into one source per frame that agrees with its windows.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <drivenshape/simulation.h>

#include "fuzz_support.h"

namespace ds = drivenshape;

namespace {

/// Frames a plan may span for the splice check (the reader allows any int range).
constexpr long long kSpliceFrames = 4096;

void checkWindows(const ds::SimulationPlan& plan, const char* reader) {
  int previousEnd = plan.first - 2;
  for (const ds::SimulationWindow& w : plan.windows) {
    ds::fuzz::require(
        plan.first <= w.warmupFrom && w.warmupFrom <= w.from && w.from <= w.to && w.to <= plan.last,
        reader, "a window outside the plan's frames or out of order");
    ds::fuzz::require(w.warmupFrom > previousEnd + 1, reader, "windows touching or overlapping");
    previousEnd = w.to;
  }
}

/// Splices zeros (baked) and ones (simulated) of one vertex; checks sizes and sources.
void checkSplice(const ds::SimulationPlan& plan) {
  const int frames = plan.last - plan.first + 1;
  std::vector<std::vector<float>> simulated;
  for (const ds::SimulationWindow& w : plan.windows) {
    simulated.emplace_back(3 * static_cast<std::size_t>(w.to - w.warmupFrom + 1), 1.0f);
  }
  const ds::SplicedShot shot = ds::spliceSimulation(
      plan, 1, std::vector<float>(3 * static_cast<std::size_t>(frames), 0.0f), simulated);
  const char* splice = "spliceSimulation";
  ds::fuzz::require(shot.sources.size() == static_cast<std::size_t>(frames) &&
                        shot.positions.size() == 3 * shot.sources.size(),
                    splice, "not one source and one position per frame");
  for (int f = plan.first; f <= plan.last; ++f) {
    const std::size_t i = static_cast<std::size_t>(f - plan.first);
    bool inside = false;
    for (const ds::SimulationWindow& w : plan.windows) {
      inside = inside || (w.from <= f && f <= w.to);
    }
    const float x = shot.positions[3 * i];
    ds::fuzz::require(inside == (shot.sources[i] == ds::FrameSource::kSimulated), splice,
                      "a handed-back frame not simulated, or another frame called simulated");
    ds::fuzz::require(x >= 0.0f && x <= 1.0f, splice, "a position outside its baked and simulated");
    ds::fuzz::require((shot.sources[i] == ds::FrameSource::kBaked) == (x == 0.0f) &&
                          (shot.sources[i] == ds::FrameSource::kSimulated) == (x == 1.0f),
                      splice, "a source that does not say what the position is");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  ds::fuzz::expectOnlyErrors("parseSimulationPlan", [&] {
    const ds::SimulationPlan plan = ds::parseSimulationPlan(text, "fuzz.json");
    const char* reader = "parseSimulationPlan";
    checkWindows(plan, reader);
    std::string written;
    ds::fuzz::expectSuccess("simulationPlanJson", [&] {
      written = ds::simulationPlanJson(plan);
      ds::fuzz::require(
          ds::simulationPlanJson(ds::parseSimulationPlan(written, "again.json")) == written, reader,
          "a plan that does not read back as written");
    });
    if (static_cast<long long>(plan.last) - plan.first < kSpliceFrames) {
      ds::fuzz::expectSuccess("spliceSimulation", [&] { checkSplice(plan); });
    }
  });
  return 0;
}
