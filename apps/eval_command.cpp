// SPDX-License-Identifier: Apache-2.0
#include "eval_command.h"

#include <cstdio>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include <drivenshape/coverage_check.h>
#include <drivenshape/database.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluate.h>
#include <drivenshape/frames.h>
#include <drivenshape/mesh.h>

#include "atomic_file.h"
#include "json_text.h"

#include "cli_args.h"
#include "device_choice.h"

namespace drivenshape::cli {
namespace {

/// A number for the table: `digits` significant digits, or "-" when `known` is false.
std::string cell(double value, bool known = true, int digits = 6) {
  if (!known) {
    return "-";
  }
  std::ostringstream out;
  out << std::setprecision(digits) << value;
  return out.str();
}

/// A strain figure (a fraction) as a percentage for the table: "3.214%".
std::string percent(double fraction) {
  return cell(100.0 * fraction, true, 4) + "%";
}

/// The rows of the side-by-side table: one column per sequence (bake, baseline, truth).
void printTable(const ShotEvaluation& e, std::ostream& out) {
  std::vector<const ClothMetrics*> columns{&e.bake};
  if (e.hasBaseline) {
    columns.push_back(&e.baseline);
  }
  columns.push_back(&e.truth);
  const bool jumps = e.frames.size() > 1;
  auto row = [&](const std::string& label, auto&& valueOf) {
    out << std::left << std::setw(26) << label << std::right;
    for (const ClothMetrics* c : columns) {
      out << std::setw(14) << valueOf(*c);
    }
    out << "\n";
  };
  row("", [](const ClothMetrics& c) { return c.name; });
  auto isTruth = [&](const ClothMetrics& c) { return &c == &e.truth; };
  row("error mean", [&](const ClothMetrics& c) { return cell(c.mean, !isTruth(c)); });
  row("error rms", [&](const ClothMetrics& c) { return cell(c.rms, !isTruth(c)); });
  row("error max", [&](const ClothMetrics& c) { return cell(c.max, !isTruth(c)); });
  row("  at frame", [&](const ClothMetrics& c) { return cell(c.maxFrame, !isTruth(c)); });
  if (e.penetrations) {
    row("inside driver / frame", [](const ClothMetrics& c) { return cell(c.meanInside, true, 4); });
    row("inside driver, max", [](const ClothMetrics& c) { return cell(c.maxInside); });
    row("  at frame",
        [](const ClothMetrics& c) { return cell(c.maxInsideFrame, c.maxInside > 0); });
    row("deepest penetration", [](const ClothMetrics& c) { return cell(c.maxDepth); });
    row("  at frame",
        [](const ClothMetrics& c) { return cell(c.maxDepthFrame, c.maxDepth > 0.0); });
  }
  if (e.strain) {
    row("mean |strain|", [](const ClothMetrics& c) { return percent(c.strain.mean); });
    row("strain p95", [](const ClothMetrics& c) { return percent(c.strain.p95); });
    row("edges > 10%", [](const ClothMetrics& c) { return percent(c.strain.overShare); });
  }
  row("largest frame jump", [&](const ClothMetrics& c) { return cell(c.maxJump, jumps); });
  row("  at frame", [&](const ClothMetrics& c) { return cell(c.maxJumpFrame, jumps); });
  if (jumps && e.truth.maxJump > 0.0) {
    row("  / truth's",
        [&](const ClothMetrics& c) { return cell(c.maxJump / e.truth.maxJump, true, 4); });
  }
}

/// The report's prediction per evaluated frame (empty without --report).
using PredictionByFrame = std::map<int, const CoverageFrame*>;

PredictionByFrame predictionByFrame(const std::optional<CoverageCheck>& coverage) {
  PredictionByFrame byFrame;
  if (coverage) {
    for (const CoverageFrame& f : coverage->frames) {
      byFrame[f.frame] = &f;
    }
  }
  return byFrame;
}

void printPerFrame(const ShotEvaluation& e, const std::optional<CoverageCheck>& coverage,
                   std::ostream& out) {
  const PredictionByFrame predicted = predictionByFrame(coverage);
  out << "frame        mean         rms         max  (vertex)        jump  truth jump";
  if (e.penetrations) {
    out << "  inside       depth  truth inside  truth depth";
  }
  if (e.strain) {
    out << "  mean |strain| %  edges > 10% %  truth mean |strain| %";
  }
  if (e.hasBaseline) {
    out << "  baseline mean  baseline jump";
    if (e.penetrations) {
      out << "  baseline inside";
    }
  }
  if (coverage) {
    out << "   predicted  flagged";
  }
  out << "\n";
  for (std::size_t f = 0; f < e.frames.size(); ++f) {
    const ClothFrameMetrics& b = e.bake.frames[f];
    const ClothFrameMetrics& t = e.truth.frames[f];
    out << std::setw(5) << b.frame << "  " << std::setw(10) << b.error.mean << "  " << std::setw(10)
        << b.error.rms << "  " << std::setw(10) << b.error.max << "  (" << b.error.maxVertex
        << ")  " << std::setw(10) << cell(b.jump, b.jump >= 0.0) << "  " << std::setw(10)
        << cell(t.jump, t.jump >= 0.0);
    if (e.penetrations) {
      out << "  " << std::setw(6) << b.inside << "  " << std::setw(10) << b.maxDepth << "  "
          << std::setw(12) << t.inside << "  " << std::setw(11) << t.maxDepth;
    }
    if (e.strain) {
      out << "  " << std::setw(15) << cell(100.0 * b.strain.mean, true, 4) << "  " << std::setw(13)
          << cell(100.0 * b.strain.overShare, true, 4) << "  " << std::setw(21)
          << cell(100.0 * t.strain.mean, true, 4);
    }
    if (e.hasBaseline) {
      const ClothFrameMetrics& l = e.baseline.frames[f];
      out << "  " << std::setw(13) << l.error.mean << "  " << std::setw(13)
          << cell(l.jump, l.jump >= 0.0);
      if (e.penetrations) {
        out << "  " << std::setw(15) << l.inside;
      }
    }
    if (coverage) {
      const auto p = predicted.find(b.frame);
      const bool known = p != predicted.end();
      out << "  " << std::setw(10) << cell(known ? p->second->predictedError : 0.0, known) << "  "
          << std::setw(7) << (known ? (p->second->flagged ? "yes" : "no") : "-");
    }
    out << "\n";
  }
}

/// JSON null for "not measured" (-1 jumps on the first frame, no driver).
nlohmann::json orNull(double value, bool known) {
  return known ? nlohmann::json(value) : nlohmann::json(nullptr);
}

/// The strain figures of a frame or a sequence, as fractions (0.1 is 10%).
void addStrainJson(nlohmann::json& j, const StrainFigures& strain) {
  j["strain_mean"] = strain.mean;
  j["strain_p95"] = strain.p95;
  j["strain_share_over_10pct"] = strain.overShare;
}

nlohmann::json frameJson(const ClothFrameMetrics& m, const ShotEvaluation& e, bool withError) {
  const bool penetrations = e.penetrations;
  nlohmann::json j;
  if (withError) {
    j["mean"] = m.error.mean;
    j["rms"] = m.error.rms;
    j["max"] = m.error.max;
    j["max_vertex"] = m.error.maxVertex;
  }
  j["jump"] = orNull(m.jump, m.jump >= 0.0);
  j["jump_vertex"] = m.jump >= 0.0 ? nlohmann::json(m.jumpVertex) : nlohmann::json(nullptr);
  if (penetrations) {
    j["inside"] = m.inside;
    j["max_depth"] = m.maxDepth;
    j["max_depth_vertex"] =
        m.maxDepthVertex >= 0 ? nlohmann::json(m.maxDepthVertex) : nlohmann::json(nullptr);
  }
  if (e.strain) {
    addStrainJson(j, m.strain);
  }
  return j;
}

nlohmann::json summaryJson(const ClothMetrics& c, const ShotEvaluation& e, bool withError) {
  const bool penetrations = e.penetrations;
  nlohmann::json j;
  j["source"] = c.source.empty() ? nlohmann::json(nullptr) : nlohmann::json(c.source);
  if (withError) {
    j["mean"] = c.mean;
    j["rms"] = c.rms;
    j["max"] = c.max;
    j["max_frame"] = c.maxFrame;
  }
  const bool jumps = c.maxJump >= 0.0;
  j["max_jump"] = orNull(c.maxJump, jumps);
  j["max_jump_frame"] = jumps ? nlohmann::json(c.maxJumpFrame) : nlohmann::json(nullptr);
  if (penetrations) {
    j["mean_inside"] = c.meanInside;
    j["max_inside"] = c.maxInside;
    j["max_inside_frame"] =
        c.maxInside > 0 ? nlohmann::json(c.maxInsideFrame) : nlohmann::json(nullptr);
    j["max_depth"] = c.maxDepth;
    j["max_depth_frame"] =
        c.maxDepth > 0.0 ? nlohmann::json(c.maxDepthFrame) : nlohmann::json(nullptr);
  }
  if (e.strain) {
    addStrainJson(j, c.strain);
  }
  return j;
}

/// A length in scene units and, after it, in mm for a scene in metres (the sample's, Blender's
/// default): "0.0124514 (12.5 mm)"; "-" when unknown.
std::string withMm(const std::optional<double>& value) {
  if (!value) {
    return "-";
  }
  std::ostringstream text;
  text << cell(*value) << " (" << std::fixed << std::setprecision(1) << *value * 1000.0 << " mm)";
  return text.str();
}

/// The coverage lines after the summary: the report's verdict against the truth.
void printCoverage(const CoverageCheck& c, const std::string& reportPath, std::ostream& out) {
  auto optional = [](const std::optional<double>& value, int digits = 6) {
    return cell(value.value_or(0.0), value.has_value(), digits);
  };
  out << "coverage (" << reportPath << "): " << c.frames.size() << " frames predicted";
  if (c.missing > 0 || c.unpredicted > 0) {
    out << " (" << c.missing << " not in the report, " << c.unpredicted << " without a prediction)";
  }
  out << "; Spearman of predicted vs true mean error " << optional(c.spearman, 4) << "\n";
  out << "  tolerance " << withMm(c.tolerance) << ": " << c.enough << " enough (covered "
      << cell(c.coveredFraction, true, 4) << "), true mean " << withMm(c.enoughTrueError) << " ("
      << c.missed << " over); " << c.flagged << " flagged, true mean " << withMm(c.flaggedTrueError)
      << "\n";
  if (!c.frames.empty()) {
    out << "  predicted mean vertex error: mean " << withMm(c.predictedMean) << ", max "
        << withMm(c.predictedMax) << " at frame " << c.predictedMaxFrame << "\n";
  }
  out << "  verdict ";
  if (!c.verdictHolds) {
    out << "not tested: no frame is predicted enough\n";
  } else if (c.level > 0.0) {
    out << (*c.verdictHolds ? "holds" : "fails") << ": " << cell(100.0 * *c.withinShare, true, 3)
        << "% of the enough frames are within the "
        << "tolerance (the report's level " << cell(100.0 * c.level, true, 3) << "%)\n";
  } else {
    out << (*c.verdictHolds ? "holds: the enough frames' true mean error is within the tolerance"
                            : "fails: the enough frames' true mean error is over the tolerance")
        << " (a report without a level)\n";
  }
  out << "  (mm: scene units x 1000, for a scene in metres)\n";
}

template <typename T>
nlohmann::json optionalJson(const std::optional<T>& value) {
  return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

nlohmann::json coverageJson(const CoverageCheck& c, const std::string& reportPath) {
  return nlohmann::json{{"report", reportPath},
                        {"frames", c.frames.size()},
                        {"missing", c.missing},
                        {"unpredicted", c.unpredicted},
                        {"spearman", optionalJson(c.spearman)},
                        {"tolerance", c.tolerance},
                        {"covered_fraction", c.coveredFraction},
                        {"enough", c.enough},
                        {"flagged", c.flagged},
                        {"enough_true_error", optionalJson(c.enoughTrueError)},
                        {"flagged_true_error", optionalJson(c.flaggedTrueError)},
                        {"missed", c.missed},
                        {"level", c.level},
                        {"within_share", optionalJson(c.withinShare)},
                        {"verdict_holds", optionalJson(c.verdictHolds)}};
}

nlohmann::json reportJson(const ShotEvaluation& e, const std::string& driverPath,
                          const std::string& device, const std::optional<CoverageCheck>& coverage,
                          const std::string& reportPath) {
  const PredictionByFrame predicted = predictionByFrame(coverage);
  nlohmann::json frames = nlohmann::json::array();
  for (std::size_t f = 0; f < e.frames.size(); ++f) {
    const ClothFrameMetrics& b = e.bake.frames[f];
    // The bake's error stays flat on each frame (the format before the side-by-side figures).
    nlohmann::json entry{{"frame", b.frame},
                         {"mean", b.error.mean},
                         {"rms", b.error.rms},
                         {"max", b.error.max},
                         {"max_vertex", b.error.maxVertex}};
    entry["bake"] = frameJson(b, e, true);
    entry["truth"] = frameJson(e.truth.frames[f], e, false);
    if (e.hasBaseline) {
      entry["baseline"] = frameJson(e.baseline.frames[f], e, true);
    }
    if (coverage) {
      const auto p = predicted.find(b.frame);
      entry["coverage"] = p == predicted.end()
                              ? nlohmann::json(nullptr)
                              : nlohmann::json{{"predicted_error", p->second->predictedError},
                                               {"flagged", p->second->flagged},
                                               {"true_error", p->second->trueError}};
    }
    frames.push_back(entry);
  }
  nlohmann::json summary{{"bake", summaryJson(e.bake, e, true)},
                         {"truth", summaryJson(e.truth, e, false)}};
  if (e.hasBaseline) {
    summary["baseline"] = summaryJson(e.baseline, e, true);
  }
  return nlohmann::json{
      {"truth", e.truth.source},
      {"bake", e.bake.source},
      {"vertices", e.vertexCount},
      {"mean", e.bake.mean},
      {"rms", e.bake.rms},
      {"max", e.bake.max},
      {"max_frame", e.bake.maxFrame},
      {"driver", driverPath.empty() ? nlohmann::json(nullptr) : nlohmann::json(driverPath)},
      {"driver_vertices", e.driverVertexCount},
      {"device", device},
      {"penetrations", e.penetrations},
      {"untrusted_driver", !e.untrustedDriver.empty()},
      {"strain", e.strain},
      {"edges", e.edgeCount},
      {"zero_length_edges", e.zeroLengthEdges},
      {"baseline", e.hasBaseline},
      {"summary", summary},
      {"coverage", coverage ? coverageJson(*coverage, reportPath) : nlohmann::json(nullptr)},
      {"frames", frames}};
}

ArgParser evalParser() {
  ArgParser parser(
      "drivenshape eval --truth CACHE --bake CACHE --frames RANGE [--db DB | --driven-mesh "
      "M.obj] [--driver CACHE (--driver-mesh M.obj | --db DB)] [--baseline] [--report PATH]",
      "Compares a bake with a truth cache (e.g. the simulation it replaces): mean, RMS and max "
      "per-vertex distance, and the largest frame-to-frame jump of the bake and of the truth. "
      "With the cloth's rest mesh (--db or --driven-mesh): the strain of the cloth's edges "
      "(|edge| / |rest edge| - 1) of every sequence: mean |strain|, its nearest-rank "
      "95th percentile and the share of edges over 10%. "
      "With the shot's driver: cloth vertices inside the driver per frame and the deepest one, "
      "for the bake and the truth (exact closest triangle, angle-weighted pseudo-normal sign). "
      "With --baseline: the same figures for the binding baseline (the rest cloth bound to the "
      "rest driver and carried along, what `bake --weights bind --no-resolve` writes). With "
      "--report: the bake report's coverage verdict against the truth.");
  parser.option("--truth", "CACHE", "reference cache (.pc2 or name.####.exr)", "", true)
      .option("--bake", "CACHE", "baked cache to judge", "", true)
      .option("--frames", "RANGE", "frames to compare (jumps follow this order)", "", true)
      .option("--json", "PATH", "also write the figures as JSON")
      .flag("--per-frame", "print every frame, not only the summary")
      .option("--driver", "CACHE", "the shot's driver cache: penetration figures")
      .option("--driver-mesh", "M.obj", "the driver's rest mesh (its triangles; rest pose)")
      .option("--driven-mesh", "M.obj", "the cloth's rest mesh (strain; for --baseline)")
      .option("--db", "DB", "take both rest meshes from this database instead (strain on)")
      .flag("--baseline", "add the binding baseline for the same frames (needs --driver)")
      .option("--bind", "MAP", "binding mask (JSON) for the baseline, as in bake --bind")
      .flag("--untrusted-driver",
            "evaluate with a driver mesh that is not closed, manifold and consistently "
            "oriented (refused otherwise): no penetration figures")
      .option("--report", "PATH",
              "the bake's report (bake --report, pose model): its predicted errors and "
              "coverage verdict against the truth")
      .option("--device", "SPEC", "closest-triangle search: host, auto, cpu, gpu, index, name",
              "host")
      .option("--threads", "N", "host threads (0 = all cores)", "0")
      .option("--batch", "N", "frames per closest-triangle call (bounds memory)", "16")
      .epilog("Exit codes: 0 ok, 2 usage, 3 input, 4 output, 5 OpenCL device.");
  return parser;
}

/// Refuses the driver options without --driver, --baseline without the meshes it needs, and
/// --bind without --baseline; checks the --json output before anything is read.
void checkEvalUsage(const ArgParser& parser) {
  const bool baseline = parser.has("--baseline");
  if (parser.has("--db") && (parser.has("--driver-mesh") || parser.has("--driven-mesh"))) {
    DS_THROW(kUsage,
             "--db already gives both rest meshes; drop --driver-mesh/--driven-mesh or "
             "--db");
  }
  if (!parser.has("--driver")) {
    for (const char* flag : {"--driver-mesh", "--bind", "--untrusted-driver"}) {
      if (parser.has(flag)) {
        DS_THROW(kUsage, flag,
                 " is only used with --driver (penetrations, baseline); pass "
                 "--driver CACHE too or drop ",
                 flag);
      }
    }
    if (baseline) {
      DS_THROW(kUsage,
               "--baseline needs the shot's driver: pass --driver CACHE with "
               "--driver-mesh M.obj --driven-mesh M.obj or --db DB");
    }
  } else if (!parser.has("--driver-mesh") && !parser.has("--db")) {
    DS_THROW(kUsage,
             "--driver needs the driver's rest mesh for the penetration figures: pass "
             "--driver-mesh M.obj or --db DB");
  }
  if (baseline && !parser.has("--driven-mesh") && !parser.has("--db")) {
    DS_THROW(kUsage,
             "--baseline needs the cloth's rest mesh: pass --driven-mesh M.obj or "
             "--db DB");
  }
  if (parser.has("--bind") && !baseline) {
    DS_THROW(kUsage, "--bind only shapes the baseline; add --baseline or drop --bind");
  }
  if (parser.has("--json")) {
    checkOutputFolderWritable(parser.get("--json"));
    std::vector<NamedPath> inputs = givenPaths(parser, {"--truth", "--bake", "--driver"}, true);
    const std::vector<NamedPath> files =
        givenPaths(parser, {"--driver-mesh", "--driven-mesh", "--db", "--bind", "--report"});
    inputs.insert(inputs.end(), files.begin(), files.end());
    checkDistinctPaths(givenPaths(parser, {"--json"}), parseFrameRange(parser.get("--frames")),
                       inputs);
  }
}

/// What evaluateShot reads, owned here: `input` points into the rest.
struct EvalInputs {
  std::unique_ptr<PointCacheReader> truth;
  std::unique_ptr<PointCacheReader> baked;
  std::unique_ptr<PointCacheReader> driver;
  std::optional<Database> db;
  Mesh driverMesh;
  Mesh drivenMesh;
  std::optional<BindingMask> mask;
  std::unique_ptr<Device> device;  ///< the closest-triangle search's (host without --driver)
  std::string deviceName = "none";
  ShotEvaluationInput input;
};

/// The rest meshes given: both of --db, or the OBJs of --driver-mesh and --driven-mesh. The
/// cloth's turns on the strain figures.
void openRestMeshes(const ArgParser& parser, EvalInputs& in) {
  if (parser.has("--db")) {
    in.db = loadDatabase(parser.get("--db"));
    in.input.driverMesh = &in.db->driverMesh;
    in.input.drivenMesh = &in.db->drivenMesh;
    in.input.driverMeshName = in.input.drivenMeshName = parser.get("--db");
    return;
  }
  if (parser.has("--driver-mesh")) {
    in.driverMesh = readObj(parser.get("--driver-mesh"));
    in.input.driverMesh = &in.driverMesh;
    in.input.driverMeshName = parser.get("--driver-mesh");
  }
  if (parser.has("--driven-mesh")) {
    in.drivenMesh = readObj(parser.get("--driven-mesh"));
    in.input.drivenMesh = &in.drivenMesh;
    in.input.drivenMeshName = parser.get("--driven-mesh");
  }
}

/// With --driver: the driver cache, the binding mask and the closest-triangle search on
/// --device.
void openShotDriver(const ArgParser& parser, EvalInputs& in) {
  // EXR driver caches carry a topology hash: it must be the driver mesh's.
  in.driver = openPointCache(parser.get("--driver"), topologyHash(*in.input.driverMesh));
  in.input.driver = in.driver.get();
  if (parser.has("--bind")) {
    in.mask = readBindingMask(parser.get("--bind"), *in.input.driverMesh, *in.input.drivenMesh);
    in.input.mask = &*in.mask;
  }
  in.device = openCliDevice(parser.get("--device"), std::cerr);
  in.deviceName = in.device->isOpenCl() ? in.device->description() : "host";
}

void openEvalInputs(const ArgParser& parser, EvalInputs& in) {
  in.truth = openPointCache(parser.get("--truth"));
  in.baked = openPointCache(parser.get("--bake"));
  in.input.truth = in.truth.get();
  in.input.bake = in.baked.get();
  in.input.baseline = parser.has("--baseline");
  in.input.batch = parser.getInt("--batch", 1);
  in.input.threads = parser.getInt("--threads", 0);
  in.input.untrustedDriver = parser.has("--untrusted-driver");
  openRestMeshes(parser, in);
  if (parser.has("--driver")) {
    openShotDriver(parser, in);
  } else {
    in.device = makeHostDevice();
  }
}

/// What the strain figures cover, or why there are none.
void printStrainNote(const ShotEvaluation& e, const std::string& drivenMeshName,
                     std::ostream& out) {
  if (!e.strain) {
    out << "strain: not measured ("
        << (drivenMeshName.empty()
                ? "no cloth rest mesh: pass --db DB or --driven-mesh M.obj"
                : "the cloth's rest mesh '" + drivenMeshName + "' has no edge of non-zero length")
        << ")\n";
    return;
  }
  out << "strain: |edge| / |rest edge| - 1 over the " << e.edgeCount
      << " edges of the cloth's rest mesh '" << drivenMeshName
      << "', in %; p95 the nearest-rank 95th percentile of |strain| (per frame over its edges, "
         "in the table over every edge of every frame)";
  if (e.zeroLengthEdges > 0) {
    out << "; " << e.zeroLengthEdges << " edges of zero rest length left out";
  }
  out << "\n";
}

/// The summary on stdout: the sizes, every frame with --per-frame, the side-by-side table, the
/// overall figures and the coverage verdict.
void printEvaluation(const ShotEvaluation& result, const std::optional<CoverageCheck>& coverage,
                     const std::vector<int>& frames, const std::string& deviceName,
                     const std::string& drivenMeshName, bool perFrame,
                     const std::string& reportPath) {
  std::cout << "eval: " << frames.size() << " frames (" << formatFrameRange(frames) << ") x "
            << result.vertexCount << " cloth vertices";
  if (result.penetrations) {
    std::cout << "; driver " << result.driverVertexCount << " vertices; closest triangles on "
              << deviceName;
  }
  std::cout << "\nlengths (errors, depths, jumps) in scene units, the caches' own (metres in a "
               "Blender scene with its default units); counts in cloth vertices\n";
  printStrainNote(result, drivenMeshName, std::cout);
  std::cout << std::setprecision(6);
  if (perFrame) {
    printPerFrame(result, coverage, std::cout);
  }
  printTable(result, std::cout);
  std::cout << "overall over " << result.frames.size() << " frames x " << result.vertexCount
            << " vertices: mean " << result.bake.mean << ", rms " << result.bake.rms << ", max "
            << result.bake.max << " (frame " << result.bake.maxFrame << ")\n";
  if (coverage) {
    printCoverage(*coverage, reportPath, std::cout);
  }
}

}  // namespace

int runEval(const std::vector<std::string>& args) {
  ArgParser parser = evalParser();
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  const std::vector<int> frames = parseFrameRange(parser.get("--frames"));
  checkEvalUsage(parser);
  // Read before the evaluation, so a bad report fails at once.
  std::optional<BakeReportCoverage> report;
  if (parser.has("--report")) {
    report = readBakeReportCoverage(parser.get("--report"));
  }
  EvalInputs in;
  openEvalInputs(parser, in);

  const ShotEvaluation result = evaluateShot(in.input, frames, *in.device);
  if (!result.untrustedDriver.empty()) {
    std::cerr << "warning: " << result.untrustedDriver << "\n";
  }
  std::optional<CoverageCheck> coverage;
  if (report) {
    coverage = checkCoverage(*report, result);
  }
  const std::string reportPath = parser.has("--report") ? parser.get("--report") : std::string();
  printEvaluation(result, coverage, frames, in.deviceName, in.input.drivenMeshName,
                  parser.has("--per-frame"), reportPath);
  if (parser.has("--json")) {
    const nlohmann::json json =
        reportJson(result, parser.has("--driver") ? parser.get("--driver") : std::string(),
                   in.deviceName, coverage, reportPath);
    writeFileAtomically(parser.get("--json"), jsonText(json, 1) + "\n");
  }
  return 0;
}

}  // namespace drivenshape::cli
