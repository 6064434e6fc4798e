// SPDX-License-Identifier: Apache-2.0
// `drivenshape db build`: the database of a reference clip, the pose model over it and any
// extra clips (--also), and the frames worth simulating next (--suggest).

#include "commands.h"

#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include <drivenshape/database.h>
#include <drivenshape/database_build.h>
#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/mesh_check.h>
#include "atomic_file.h"
#include "json_text.h"

#include "cli_args.h"

namespace drivenshape::cli {
namespace {

/// A cache with the frames to read: CACHE[:FRAMES].
struct CacheSpec {
  std::string path;
  std::vector<int> frames;  ///< empty = every frame
};

/// Splits CACHE[:FRAMES] at the last ':' when what follows is a frame list (digits, '-', ',',
/// 'x') and the whole word is not an existing file.
CacheSpec parseCacheSpec(const std::string& word) {
  const std::size_t colon = word.rfind(':');
  if (colon == std::string::npos || colon + 1 == word.size() || std::filesystem::exists(word)) {
    return {word, {}};
  }
  const std::string range = word.substr(colon + 1);
  if (range.find_first_not_of("0123456789-,x") != std::string::npos) {
    return {word, {}};
  }
  return {word.substr(0, colon), parseFrameRange(range)};
}

std::string framesText(const std::vector<int>& frames) {
  return frames.empty() ? std::string("all") : formatFrameRange(frames);
}

/// Prints the suggestions (stdout) and writes them as JSON to `jsonPath` if not empty.
void reportSuggestions(const std::vector<ReferenceSuggestion>& suggestions,
                       const CacheSpec& candidate, const std::vector<CacheSpec>& shots,
                       const Database& db, const std::string& jsonPath) {
  std::cout << "suggested frames of " << candidate.path
            << " to simulate and add (mean predicted error of the shot frames before -> after, "
               "scene units):\n";
  for (std::size_t i = 0; i < suggestions.size(); ++i) {
    const ReferenceSuggestion& s = suggestions[i];
    std::cout << "  " << std::setw(3) << i + 1 << "  frame " << std::setw(6) << s.frame << "  "
              << s.errorBefore << " -> " << s.errorAfter << "\n";
  }
  if (jsonPath.empty()) {
    return;
  }
  nlohmann::json shotList = nlohmann::json::array();
  for (const CacheSpec& shot : shots) {
    shotList.push_back({{"driver", shot.path}, {"frames", framesText(shot.frames)}});
  }
  nlohmann::json list = nlohmann::json::array();
  for (const ReferenceSuggestion& s : suggestions) {
    list.push_back({{"frame", s.frame},
                    {"error_before", s.errorBefore},
                    {"error_after", s.errorAfter},
                    {"sigma_before", s.sigmaBefore},
                    {"sigma_after", s.sigmaAfter}});
  }
  const nlohmann::json report{
      {"candidate", {{"driver", candidate.path}, {"frames", framesText(candidate.frames)}}},
      {"shots", shotList},
      {"model",
       {{"reference_frames", db.poseModel.frameCount()},
        {"error_bias", db.poseModel.errorBias},
        {"error_scale", db.poseModel.errorScale}}},
      {"suggestions", list}};
  writeFileAtomically(jsonPath, jsonText(report, 1) + "\n");
}

ArgParser dbBuildParser() {
  ArgParser parser(
      "drivenshape db build --driver-mesh M.obj --driven-mesh M.obj --driver CACHE "
      "--driven CACHE -o DB",
      "Builds a DrivenShape database from a reference animation: a greedy farthest-point pick "
      "of driver shapes (seeded with --add-frames, else with the settled rest pose: the "
      "latest candidate frame whose driver is as close to the rest driver as any, i.e. the end "
      "of the opening hold, once the cloth has draped), each paired with the driven shape of "
      "the same frame. --also adds reference clips the pose model is fitted on; --suggest lists "
      "the frames of a candidate clip worth simulating for the given shots.");
  parser.option("--driver-mesh", "M.obj", "driver rest mesh (topology, groups)", "", true)
      .option("--driven-mesh", "M.obj", "driven rest mesh (topology, UVs, groups)", "", true)
      .option("--driver", "CACHE", "driver reference cache (.pc2 or name.####.exr)", "", true)
      .option("--driven", "CACHE", "driven reference cache, same frames", "", true)
      .option("--frames", "RANGE", "candidate frames, e.g. 1-320 or 21-320x2", "all")
      .repeated("--also", "DRIVER DRIVEN[:FRAMES]", 2,
                "another reference clip of the same character and cloth: the pose model is "
                "fitted over its frames too (all, or FRAMES); the shapes are still picked from "
                "--driver/--driven")
      .option("--add-frames", "LIST", "frames always kept (they seed the pick)")
      .option("--remove-frames", "LIST", "frames never kept");
  // The settings (count, duplicate tolerance, the pose model's): rows of the settings table,
  // which the Python module's build_database reads too.
  parser.settings(SettingScope::kBuild)
      .option("--model-json", "PATH",
              "also write the pose model's fit as JSON: kernel settings, the error line and "
              "the verdict's calibration, every reference frame's cross-validated error, and "
              "with --also what each clip adds")
      .option("--rig", "RIG.json",
              "take the parts from a rig instead: bone_names, bones (name, parent) and "
              "driver_weights (one row per driver vertex); each vertex goes to its heaviest "
              "bone")
      .option("--suggest", "N",
              "after fitting, print the N frames of --candidate that, simulated and added with "
              "--also, would most lower the predicted error of the --shot frames (fewer if the "
              "candidate clip is shorter)")
      .option("--candidate", "DRIVER[:FRAMES]", "the driver clip --suggest picks frames from")
      .repeated("--shot", "DRIVER[:FRAMES]", 1, "a shot's driver cache --suggest improves")
      .option("--suggest-json", "PATH", "also write the suggestions as JSON")
      .option("-o", "DB", "database file to write (optional with --suggest)")
      .flag("--quiet", "do not list the picks")
      .flag("--untrusted-driver",
            "build from a driver mesh that is not closed, manifold and consistently oriented "
            "(refused otherwise); its bakes need --untrusted-driver too")
      .epilog(
          "Exit codes: 0 success, 1 internal error, 2 usage, 3 input (a missing or "
          "malformed file, a cache that does not match the meshes), 4 output, 6 numerical.");
  return parser;
}

/// The pick and pose model settings of the command line, checked.
DatabaseBuildOptions buildOptionsFrom(const ArgParser& parser) {
  DatabaseBuildOptions options;
  if (parser.has("--frames")) {
    options.frames = parseFrameRange(parser.get("--frames"));
  }
  if (parser.has("--add-frames")) {
    options.addFrames = parseFrameRange(parser.get("--add-frames"));
  }
  if (parser.has("--remove-frames")) {
    options.removeFrames = parseFrameRange(parser.get("--remove-frames"));
  }
  readSettings(parser, options);
  return options;
}

/// Refuses the options that --suggest needs without it (and -o missing), or lacks with it, and
/// --also clips without a pose model.
void checkSuggestUsage(const ArgParser& parser, bool suggest, bool poseModel) {
  if (!suggest) {
    for (const char* name : {"--candidate", "--shot", "--suggest-json"}) {
      if (parser.has(name)) {
        DS_THROW(kUsage, name, " goes with --suggest N");
      }
    }
    if (!parser.has("-o")) {
      DS_THROW(kUsage,
               "missing required option -o DB for `db build` (only --suggest may go "
               "without it); see --help");
    }
  } else {
    if (!parser.has("--candidate") || !parser.has("--shot")) {
      DS_THROW(kUsage,
               "--suggest needs --candidate DRIVER[:FRAMES] and at least one --shot "
               "DRIVER[:FRAMES]");
    }
    if (!poseModel) {
      DS_THROW(kUsage, "--suggest reads the pose model; drop --model none");
    }
  }
  if (!parser.all("--also").empty() && !poseModel) {
    DS_THROW(kUsage, "--also clips feed the pose model; drop --model none or the --also clips");
  }
}

/// Everything `db build` asks for, checked before anything is read.
struct DbBuildRequest {
  DatabaseBuildOptions options;
  int suggestCount = 0;                                 ///< 0 without --suggest
  std::string output;                                   ///< -o, empty when not given
  std::string jsonPath;                                 ///< --suggest-json, empty when not given
  std::string modelJsonPath;                            ///< --model-json, empty when not given
  std::vector<std::pair<std::string, CacheSpec>> also;  ///< --also DRIVER DRIVEN[:FRAMES]
  CacheSpec candidate;
  std::vector<CacheSpec> shots;
};

/// Every file `db build` reads, for checkDistinctPaths: the meshes, the rig, and every cache
/// (--driver, --driven, --also, --candidate, --shot), a sequence with all its frames.
std::vector<NamedPath> dbBuildInputPaths(const ArgParser& parser, const DbBuildRequest& request) {
  std::vector<NamedPath> inputs = givenPaths(parser, {"--driver-mesh", "--driven-mesh", "--rig"});
  const auto cache = [&inputs](const char* option, const std::string& path) {
    inputs.push_back({option, path, hasFramePattern(path)});
  };
  cache("--driver", parser.get("--driver"));
  cache("--driven", parser.get("--driven"));
  for (const auto& [driver, driven] : request.also) {
    cache("--also", driver);
    cache("--also", driven.path);
  }
  if (!request.candidate.path.empty()) {
    cache("--candidate", request.candidate.path);
  }
  for (const CacheSpec& shot : request.shots) {
    cache("--shot", shot.path);
  }
  return inputs;
}

/// Usage errors first: the options, the output folders, distinct paths, then every cache word.
DbBuildRequest dbBuildRequestFrom(const ArgParser& parser) {
  DbBuildRequest request;
  request.options = buildOptionsFrom(parser);
  const bool suggest = parser.has("--suggest");
  request.suggestCount = suggest ? parser.getInt("--suggest", 1) : 0;
  checkSuggestUsage(parser, suggest, request.options.poseModel);
  request.output = parser.has("-o") ? parser.get("-o") : std::string();
  if (!request.output.empty()) {
    checkOutputFolderWritable(request.output);
  }
  request.jsonPath = parser.has("--suggest-json") ? parser.get("--suggest-json") : "";
  if (!request.jsonPath.empty()) {
    checkOutputFolderWritable(request.jsonPath);
  }
  request.modelJsonPath = parser.has("--model-json") ? parser.get("--model-json") : "";
  if (!request.modelJsonPath.empty()) {
    if (!request.options.poseModel) {
      DS_THROW(kUsage, "--model-json writes the pose model's fit; drop --model none");
    }
    checkOutputFolderWritable(request.modelJsonPath);
  }
  for (const std::vector<std::string>& words : parser.all("--also")) {
    request.also.emplace_back(words[0], parseCacheSpec(words[1]));
  }
  if (suggest) {
    request.candidate = parseCacheSpec(parser.get("--candidate"));
  }
  for (const std::vector<std::string>& words : parser.all("--shot")) {
    request.shots.push_back(parseCacheSpec(words[0]));
  }
  checkDistinctPaths(givenPaths(parser, {"-o", "--suggest-json", "--model-json"}), {},
                     dbBuildInputPaths(parser, request));
  return request;
}

/// The meshes and caches `db build` reads; the clips point into `caches`.
struct DbBuildInputs {
  Mesh driverMesh;
  Mesh drivenMesh;
  std::unique_ptr<PointCacheReader> driver;
  std::unique_ptr<PointCacheReader> driven;
  std::vector<std::unique_ptr<PointCacheReader>> caches;
  std::vector<ReferenceClip> clips;
  DriverClip candidate;
  std::vector<DriverClip> shots;
};

/// Reads the meshes (warning about an untrusted driver), the rig's parts into the request's
/// options, and opens every cache.
DbBuildInputs openDbBuildInputs(const ArgParser& parser, DbBuildRequest& request) {
  DbBuildInputs in;
  in.driverMesh = readObj(parser.get("--driver-mesh"));
  const std::string untrusted =
      checkDriverMesh(in.driverMesh, parser.get("--driver-mesh"), DriverMeshUse::kDatabase,
                      parser.has("--untrusted-driver"));
  if (!untrusted.empty()) {
    std::cerr << "warning: " << untrusted << "\n";
  }
  in.drivenMesh = readObj(parser.get("--driven-mesh"));
  if (parser.has("--rig")) {
    readRigParts(parser.get("--rig"), in.driverMesh.vertexCount(), request.options.model.partOf,
                 request.options.model.parentOf);
  }
  in.driver = openPointCache(parser.get("--driver"), 0);
  in.driven = openPointCache(parser.get("--driven"), 0);
  for (const auto& [driverPath, drivenSpec] : request.also) {
    in.caches.push_back(openPointCache(driverPath, 0));
    in.caches.push_back(openPointCache(drivenSpec.path, 0));
    in.clips.push_back(
        {in.caches[in.caches.size() - 2].get(), in.caches.back().get(), drivenSpec.frames});
  }
  if (request.suggestCount > 0) {
    in.caches.push_back(openPointCache(request.candidate.path, 0));
    in.candidate = {in.caches.back().get(), request.candidate.frames};
    for (const CacheSpec& spec : request.shots) {
      in.caches.push_back(openPointCache(spec.path, 0));
      in.shots.push_back({in.caches.back().get(), spec.frames});
    }
  }
  return in;
}

/// --model-json: the pose model's fit (PoseModel's diagnostics, which the file does not keep).
void writeModelJson(const std::string& path, const Database& db) {
  const PoseModel& m = db.poseModel;
  nlohmann::json clips = nlohmann::json::array();
  std::vector<int> clipOfFrame;
  const std::size_t clipCount = std::max<std::size_t>(1, m.clipErrors.size());
  for (std::size_t c = 0; c < clipCount; ++c) {
    const bool main = c == 0;
    const int frames = m.clipErrors.empty() ? m.frameCount() : m.clipErrors[c].frames;
    clipOfFrame.insert(clipOfFrame.end(), static_cast<std::size_t>(frames), static_cast<int>(c));
    nlohmann::json clip{
        {"driver", main ? db.driverSource : db.extraClips[c - 1].driverSource},
        {"driven", main ? db.drivenSource : db.extraClips[c - 1].drivenSource},
        {"frames", frames},
        {"cross_validation_error",
         m.clipErrors.empty() ? m.crossValidationError : m.clipErrors[c].withAll[c]}};
    if (!m.clipErrors.empty()) {
      clip["errors_without_it"] = m.clipErrors[c].without;
    }
    clips.push_back(std::move(clip));
  }
  nlohmann::json frames = nlohmann::json::array();
  for (std::size_t i = 0; i < m.frameErrors.size() && i < m.frameSigmas.size(); ++i) {
    frames.push_back({{"frame", m.frames[i]},
                      {"clip", clipOfFrame[i]},
                      {"sigma", m.frameSigmas[i]},
                      {"error", m.frameErrors[i]},
                      {"predicted_error", m.predictedError(m.frameSigmas[i])},
                      {"error_bound", m.errorBound(m.frameSigmas[i])}});
    if (i < m.leftOutErrors.size()) {
      frames.back()["left_out_error"] = m.leftOutErrors[i];
      frames.back()["left_out_sigma"] = m.leftOutSigmas[i];
    }
  }
  nlohmann::json perClip = nlohmann::json::array();
  for (const ClipMixtureTrial& trial : m.clipMixtureTrials) {
    perClip.push_back({{"weight", trial.weight}, {"left_out_error", trial.leftOutError}});
  }
  // The share of the held-out reference frames the verdict calls enough, per tolerance (a
  // share of the cloth's rest diagonal).
  nlohmann::json heldOutEnough = nlohmann::json::array();
  for (const VerdictOutlook& at : verdictOutlook(m, db.drivenMesh)) {
    heldOutEnough.push_back(
        {{"tolerance_share", at.share}, {"tolerance", at.tolerance}, {"enough", at.enough}});
  }
  nlohmann::json report{
      {"units", "scene units (mean vertex distance)"},
      {"reference_frames", m.frameCount()},
      {"kernel",
       {{"length_scale", m.lengthScale}, {"linear_weight", m.linearWeight}, {"ridge", m.ridge}}},
      {"rank", m.rank()},
      {"sibling_weight", m.siblingWeight},
      {"cross_validation_error", m.crossValidationError},
      {"binding_error", m.bindingError},
      {"error_line", {{"bias", m.errorBias}, {"scale", m.errorScale}}},
      {"verdict",
       {{"level", m.verdictLevel},
        {"margin", m.verdictMargin},
        {"smallest_bound", m.smallestErrorBound()},
        {"held_out_enough", heldOutEnough}}},
      {"clips", clips},
      {"frames", frames}};
  if (!perClip.empty()) {
    report["per_clip_models"] = {{"weight", m.clipMixtureWeight}, {"tried", perClip}};
  }
  writeFileAtomically(path, jsonText(report, 1) + "\n");
}

void saveAndDescribe(const std::string& output, const Database& db) {
  saveDatabase(output, db);
  std::cout << "database: " << absolute(output) << " (" << db.shapeCount() << " shapes, driver "
            << db.driverVertexCount() << " vertices, driven " << db.drivenVertexCount()
            << " vertices)\n";
}

/// --suggest: the frames of the candidate clip worth simulating, printed (and written as
/// JSON), then on `log` how to add them.
void runSuggest(const Database& db, const DbBuildRequest& request, const DbBuildInputs& in,
                std::ostream* log) {
  if (db.poseModel.empty()) {
    DS_THROW(kInput,
             "--suggest reads the pose model, and the reference frames were too few to "
             "fit one (it needs 10)");
  }
  const std::vector<ReferenceSuggestion> suggestions = suggestReferenceFrames(
      db, in.candidate, in.shots, request.suggestCount, request.options.model.threads, log);
  reportSuggestions(suggestions, request.candidate, request.shots, db, request.jsonPath);
  if (log != nullptr) {
    std::vector<int> frames;
    for (const ReferenceSuggestion& s : suggestions) {
      frames.push_back(s.frame);
    }
    std::sort(frames.begin(), frames.end());
    *log << "to add them: simulate the cloth of " << request.candidate.path
         << " and rebuild with --also " << request.candidate.path
         << " CLOTH.pc2:" << formatFrameRange(frames)
         << " (velocity and history read the driver's earlier frames)\n";
  }
}

}  // namespace

int runDbBuild(const std::vector<std::string>& args) {
  ArgParser parser = dbBuildParser();
  if (!parser.parse(args)) {
    std::cout << parser.help();
    return 0;
  }
  DbBuildRequest request = dbBuildRequestFrom(parser);
  const DbBuildInputs in = openDbBuildInputs(parser, request);
  std::ostream* log = parser.has("--quiet") ? nullptr : &std::cerr;
  const Database db = buildDatabase(in.driverMesh, in.drivenMesh, *in.driver, *in.driven, in.clips,
                                    request.options, log);
  if (!request.output.empty()) {
    saveAndDescribe(request.output, db);
  }
  if (!request.modelJsonPath.empty() && !db.poseModel.empty()) {
    writeModelJson(request.modelJsonPath, db);
  }
  if (request.suggestCount > 0) {
    runSuggest(db, request, in, log);
  }
  return 0;
}

}  // namespace drivenshape::cli
