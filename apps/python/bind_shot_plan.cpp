// SPDX-License-Identifier: Apache-2.0
// The shot planner (drivenshape/shot_plan.h): plan_shot for whole shots (evaluate_cache, the
// add-on's bake) and PlaybackPlanner for a timeline played frame by frame (live mode); and what
// a bake says of its shot: the driver check, the coverage verdict, its simulation runs and the
// bake report (drivenshape/bake.h, coverage_check.h), so that a tool evaluating a shot itself
// (the USD bake) checks and reports it as `drivenshape bake` does; and the strain of a frame's
// edges, as `drivenshape eval` measures it (drivenshape/evaluate.h).
#include "binding.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <map>
#include <numeric>
#include <optional>
#include <sstream>
#include <tuple>

#include <drivenshape/bake.h>
#include <drivenshape/coverage_check.h>
#include <drivenshape/database.h>
#include <drivenshape/evaluate.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/mesh.h>
#include <drivenshape/shot_plan.h>

#include "driver_check.h"

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

/// The bake result the report of an evaluated shot states: its records (each written to
/// `output` unless it names its own file), device, settings hash, warnings and seconds ("read",
/// "write", "setup", "total" and the stages by name).
BakeResult shotResult(const Evaluator& evaluator, const std::vector<FrameRecord>& records,
                      const std::string& output, const std::map<std::string, double>& seconds,
                      const std::vector<std::string>& warnings) {
  BakeResult result;
  result.frames = records;
  for (FrameRecord& record : result.frames) {
    if (record.output.empty()) {
      record.output = output;  // the file that holds every frame (a USD stage)
    }
  }
  result.device = evaluator.deviceName();
  result.settingsHash = evaluator.settingsHash();
  result.baked = static_cast<int>(records.size());
  result.warnings = warnings;
  for (const auto& [name, value] : seconds) {
    double* field = name == "read"    ? &result.times.read
                    : name == "write" ? &result.times.write
                    : name == "setup" ? &result.times.setup
                    : name == "total" ? &result.times.total
                                      : &result.times.stages[name];
    *field = value;
  }
  return result;
}

void bindShotChecks(py::module_& module) {
  module.def(
      "check_driver_scale",
      [](const Database& database, const PointCacheReader& driver, types::Frames frames) {
        const std::vector<int> list = frameList(frames);
        std::vector<std::pair<bool, std::string>> out;
        py::gil_scoped_release release;
        for (const DriverFinding& finding : checkDriver(database, driver, list)) {
          out.emplace_back(finding.refuse, finding.message);
        }
        return out;
      },
      py::arg("database"), py::arg("driver"), py::arg("frames"),
      "What `drivenshape bake` finds checking a driver against the database before it bakes: "
      "[(refuse, message)] for sampled `frames` whose edge lengths say other units (a "
      "centimetre driver for a metre database) or another character; empty when all is well. "
      "The bake refuses a finding with refuse=True (unless --force) and warns of the others.");
  module.def(
      "simulation_runs",
      [](types::Frames flagged, types::Frame first, int runUp) {
        std::vector<int> frames = frameList(flagged, "flagged");
        std::sort(frames.begin(), frames.end());
        frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
        std::vector<std::tuple<int, int, int>> out;
        for (const SimulationRun& run :
             simulationRuns(frames, frameNumber(first, "first"), runUp)) {
          out.emplace_back(run.from, run.to, run.wanted);
        }
        return out;
      },
      py::arg("flagged"), py::arg("first"), py::arg("run_up") = kSimulationRunUp,
      "The flagged frames as cloth simulation runs [(from, to, wanted)], as the bake report's "
      "coverage.simulate_runs gives them: each run of consecutive frames starts `run_up` frames "
      "earlier (never before `first`, the shot's first frame); runs that then touch merge.");
}

void bindShotReport(py::module_& module) {
  module.def(
      "shot_verdict",
      [](types::EvaluatorObject evaluatorObject,
         const std::vector<FrameRecord>& records) -> std::optional<types::JsonDict> {
        const Evaluator& evaluator = evaluatorOf(evaluatorObject);
        const std::string text = coverageVerdictJson(records, evaluator.coverageTolerance(),
                                                     evaluator.database().poseModel.verdictLevel);
        if (text == "null") {
          return std::nullopt;
        }
        return types::JsonDict(py::module_::import("json").attr("loads")(text));
      },
      py::arg("evaluator"), py::arg("records"),
      "The shot's coverage verdict over the FrameRecords of its frames, as the bake report's "
      "`coverage` object: tolerance, level, frames_checked, covered_fraction, simulate_frames, "
      "simulate_runs, run_up and verdict ('DrivenShape is enough' or 'simulate 12-20'); None "
      "when no record has a pose-model prediction (another model than the pose model).");
  module.def("merge_bake_reports", &mergeBakeReports, py::arg("texts"), py::arg("sources"),
             "One bake report (JSON text) from the JSON texts of the reports of parts of one "
             "shot (farm chunks), `sources` naming them in messages: every frame's record once "
             "in frame order, the verdict over all of them, the warnings of all, `run` and "
             "`seconds` summed. drivenshape.Error for reports of another database or settings.");
  module.def(
      "bake_report",
      [](types::EvaluatorObject evaluatorObject, const std::vector<FrameRecord>& records,
         const std::string& driver, const std::string& output,
         const std::map<std::string, double>& seconds, const std::vector<std::string>& warnings,
         int batch, int temporalWarmup, double framesPerSecond) {
        const Evaluator& evaluator = evaluatorOf(evaluatorObject);
        BakeOptions options;
        for (const FrameRecord& record : records) {
          options.frames.push_back(record.frame);
        }
        options.outputPattern = output;
        options.batchFrames = batch;
        options.temporalWarmup = temporalWarmup;
        options.framesPerSecond = framesPerSecond;
        options.evaluator = evaluator.settings();
        return bakeReportJson(evaluator.database(), driver, options, evaluator,
                              shotResult(evaluator, records, output, seconds, warnings));
      },
      py::arg("evaluator"), py::arg("records"), py::arg("driver"), py::arg("output"),
      py::arg("seconds") = std::map<std::string, double>(),
      py::arg("warnings") = std::vector<std::string>(), py::arg("batch") = kDefaultBatchFrames,
      py::arg("temporal_warmup") = kDefaultTemporalWarmup, py::arg("frames_per_second") = 24.0,
      "The JSON text of the bake report `drivenshape bake --report` writes "
      "(docs/schemas/bake_report.schema.json) for `records` evaluated by `evaluator` from the "
      "driver file `driver` into `output` (each record's output unless it names its own): the "
      "settings, every frame's record and the shot's coverage verdict. settings_hash is the "
      "evaluator's (an EXR bake's also covers its file options).");
}

/// The vertex count of a (V, 3) block of finite positions; Error(kUsage) for another shape,
/// Error(kInput) naming the first value that is not finite.
int finiteVertexBlock(const FloatArray& array, const char* what) {
  if (array.ndim() != 2 || array.dim(1) != 3) {
    DS_THROW(kUsage, what, " must be shaped (vertices, 3); got ", array.describe());
  }
  const float* values = array.data();
  for (py::ssize_t i = 0; i < array.size(); ++i) {
    if (!std::isfinite(values[i])) {
      DS_THROW(kInput, what, ": vertex ", i / 3, " is not finite (", values[i], ")");
    }
  }
  return static_cast<int>(array.dim(0));
}

/// Edges (E, 2) of integer vertex ids within [0, vertexCount); Error(kUsage) for another shape
/// or type, Error(kInput) for an id out of range (before any conversion could wrap it).
std::vector<MeshEdge> edgeList(py::handle object, int vertexCount) {
  py::module_ numpy = py::module_::import("numpy");
  const py::object array = numpy.attr("asarray")(object);
  const auto shape = array.attr("shape").cast<std::vector<py::ssize_t>>();
  const auto kind = array.attr("dtype").attr("kind").cast<std::string>();
  if (shape.size() != 2 || shape[1] != 2 || (kind != "i" && kind != "u" && shape[0] > 0)) {
    DS_THROW(kUsage,
             "edges must be integer vertex ids shaped (edges, 2), as Mesh.edges gives; "
             "got shape ",
             py::str(array.attr("shape")).cast<std::string>(), " of ",
             py::str(array.attr("dtype")).cast<std::string>());
  }
  if (shape[0] > 0 && (array.attr("min")().cast<double>() < 0.0 ||
                       array.attr("max")().cast<double>() >= vertexCount)) {
    DS_THROW(kInput, "edges name vertices outside the ", vertexCount, " of the positions");
  }
  const std::vector<int> ids = intVector(array, "edges");
  std::vector<MeshEdge> edges(ids.size() / 2);
  for (std::size_t e = 0; e < edges.size(); ++e) {
    edges[e] = {ids[2 * e], ids[2 * e + 1]};
  }
  return edges;
}

/// edge_strain's and frame_strain's arguments, checked: rest and positions of one vertex count.
struct StrainArguments {
  StrainArguments(py::handle restObject, py::handle positionsObject, py::handle edgesObject)
      : rest(restObject, "rest"), positions(positionsObject, "positions") {
    vertexCount = finiteVertexBlock(rest, "rest");
    if (finiteVertexBlock(positions, "positions") != vertexCount) {
      DS_THROW(kUsage, "positions ", positions.describe(), " and rest ", rest.describe(),
               " must hold the same vertices");
    }
    edges = edgeList(edgesObject, vertexCount);
  }
  FloatArray rest;
  FloatArray positions;
  int vertexCount = 0;
  std::vector<MeshEdge> edges;
};

void bindShotStrain(py::module_& module) {
  module.def(
      "edge_strain",
      [](types::ArrayLike rest, types::ArrayLike positions, types::ArrayLike edges) {
        const StrainArguments in(rest, positions, edges);
        std::vector<double> strains;
        {
          py::gil_scoped_release release;
          strains = edgeStrains(in.rest.data(), in.positions.data(), in.vertexCount, in.edges);
        }
        const auto count = static_cast<py::ssize_t>(strains.size());
        return types::Float64Array(ownedArray(std::move(strains), {count}));
      },
      py::arg("rest"), py::arg("positions"), py::arg("edges"),
      "The strain of each edge, (E,) float64: |edge| / |rest edge| - 1 of `positions` (V, 3) "
      "against `rest` (V, 3) over `edges` (E, 2) vertex ids (Mesh.edges of the rest mesh). "
      "0.2 is an edge stretched by 20%, -0.2 one shrunk by 20%. Error kind 'input' for an "
      "edge of zero rest length, a vertex id out of range or a value that is not finite.");
  module.def(
      "frame_strain",
      [](types::ArrayLike rest, types::ArrayLike positions, types::ArrayLike edges) {
        const StrainArguments in(rest, positions, edges);
        StrainFigures f;
        {
          py::gil_scoped_release release;
          f = frameStrain(in.rest.data(), in.positions.data(), in.vertexCount, in.edges);
        }
        py::dict out;
        out["edges"] = f.values;
        out["strain_mean"] = f.mean;
        out["strain_p95"] = f.p95;
        out["strain_share_over_10pct"] = f.overShare;
        return types::StrainDict(std::move(out));
      },
      py::arg("rest"), py::arg("positions"), py::arg("edges"),
      "One frame's strain figures, as `drivenshape eval` gives them per frame (its JSON's keys): "
      "edges (how many), strain_mean (mean |strain|), strain_p95 (the nearest-rank 95th "
      "percentile of |strain|: the value at rank ceil(0.95 E) of the E values sorted "
      "ascending) and strain_share_over_10pct (the share of edges with |strain| > 0.1), as "
      "fractions (0.1 is 10%); all 0 without edges. Arguments as edge_strain.");
}

}  // namespace

void bindShotPlan(py::module_& module) {
  bindShotChecks(module);
  bindShotReport(module);
  bindShotStrain(module);
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
