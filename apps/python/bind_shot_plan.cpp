// SPDX-License-Identifier: Apache-2.0
// The shot planner (drivenshape/shot_plan.h): plan_shot for whole shots (evaluate_cache, the
// add-on's bake) and PlaybackPlanner for a timeline played frame by frame (live mode).
#include "binding.h"

#include <algorithm>
#include <climits>
#include <numeric>
#include <sstream>

#include <drivenshape/evaluator.h>
#include <drivenshape/shot_plan.h>

namespace drivenshape::python {
namespace {

/// The frames a driver source holds: a Python range of step 1 (a scene's frame range) is read
/// without listing it; anything else as frameList reads frames.
std::vector<int> availableFrames(py::handle object) {
  if (Py_IS_TYPE(object.ptr(), &PyRange_Type) &&
      py::object(object.attr("step")).equal(py::int_(1))) {
    const int start = frameNumber(object.attr("start"), "available: start");
    const long long stop = wholeNumber(object.attr("stop"), "available: stop",
                                       static_cast<long long>(INT_MIN), 1LL + INT_MAX);
    std::vector<int> frames(static_cast<std::size_t>(std::max(0LL, stop - start)));
    std::iota(frames.begin(), frames.end(), start);
    return frames;
  }
  return frameList(object, "available");
}

ShotPlanSettings planSettings(py::handle evaluator, int batch, int temporalWarmup) {
  return shotPlanSettings(evaluatorOf(evaluator), batch, temporalWarmup);
}

std::string describe(const BatchPlan& batch) {
  std::ostringstream text;
  const auto list = [&](const std::vector<int>& frames) {
    text << "[";
    for (std::size_t i = 0; i < frames.size(); ++i) {
      text << (i ? ", " : "") << frames[i];
    }
    text << "]";
  };
  text << "BatchPlan(warmup=";
  list(batch.warmup);
  text << ", frames=";
  list(batch.frames);
  text << ", first=" << batch.first << ", restart=" << (batch.restart ? "True" : "False") << ")";
  return text.str();
}

}  // namespace

void bindShotPlan(py::module_& module) {
  py::class_<BatchPlan>(module, "BatchPlan",
                        "One evaluator call of a plan: reset the temporal state when `restart`, "
                        "evaluate solve_frames (warmup then frames) with warmup=len(warmup), "
                        "keep the cloth of `frames`.")
      .def_readonly("warmup", &BatchPlan::warmup,
                    "driver frames evaluated first and dropped (ascending)")
      .def_readonly("frames", &BatchPlan::frames, "the output frames, in the order asked for")
      .def_readonly("first", &BatchPlan::first,
                    "index of frames[0] in the frames given to plan_shot")
      .def_readonly("restart", &BatchPlan::restart,
                    "reset the evaluator's temporal state (reset_temporal_bound) first")
      .def_property_readonly("solve_frames", &BatchPlan::solveFrames,
                             "warmup + frames: the driver frames to evaluate, in order")
      .def("__repr__", &describe);

  module.def(
      "plan_shot",
      [](types::EvaluatorObject evaluator, types::Frames frames, types::Frames available, int batch,
         int temporalWarmup) {
        const ShotPlanSettings settings = planSettings(evaluator, batch, temporalWarmup);
        return planShot(frameList(frames), availableFrames(available), settings);
      },
      py::arg("evaluator"), py::arg("frames"), py::arg("available"),
      py::arg("batch") = kDefaultBatchFrames, py::arg("temporal_warmup") = kDefaultTemporalWarmup,
      "The batches in which `drivenshape bake` evaluates `frames` (any order) with this "
      "evaluator, from a driver source holding `available` (a list or a range): history and "
      "temporal warm-up frames, a new batch every `batch` frames and at gaps. [BatchPlan]");

  py::class_<PlaybackPlanner>(module, "PlaybackPlanner",
                              "The plan of a timeline played frame by frame (live mode): each "
                              "frame continues the evaluator or starts a batch with its warm-up, "
                              "so that it is the frame of a bake.")
      .def(py::init([](types::EvaluatorObject evaluator, int batch, int temporalWarmup) {
             return PlaybackPlanner(planSettings(evaluator, batch, temporalWarmup));
           }),
           py::arg("evaluator"), py::arg("batch") = kDefaultBatchFrames,
           py::arg("temporal_warmup") = kDefaultTemporalWarmup)
      .def(
          "next",
          [](PlaybackPlanner& planner, types::Frame frame, types::Frames available) {
            const int number = frameNumber(frame, "frame");
            return planner.next(number, availableFrames(available));
          },
          py::arg("frame"), py::arg("available"),
          "The BatchPlan that evaluates `frame` next (its warm-up from `available`); call "
          "reset() if it was not evaluated.")
      .def("reset", &PlaybackPlanner::reset, "Forgets the run: the next frame starts a batch.")
      .def_property_readonly("warmup_frames",
                             [](const PlaybackPlanner& p) { return p.settings().warmupFrames(); })
      .def_property_readonly("batch", [](const PlaybackPlanner& p) { return p.settings().batch; });
}

}  // namespace drivenshape::python
