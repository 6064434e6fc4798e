// SPDX-License-Identifier: Apache-2.0
// The settings table (drivenshape/settings_table.h): each setting of every tool declared once,
// below, with its names, range, help, use, how it enters the hash and the report and how the
// Blender add-on shows it; and the functions every tool reads it through.

#include <drivenshape/settings_table.h>

#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <type_traits>

#include <drivenshape/error.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/version.h>

#include <layer_types.h>
#include "json_text.h"
#include "settings_rows.h"
#include "stage.h"

namespace drivenshape {

// Helpers in a named namespace: the pipeline's sources are compiled as one unity file.
namespace settings_impl {

using pipeline::AddonChoice;
using pipeline::HashInput;
using pipeline::Model;
using pipeline::SettingRow;

constexpr double kNoLimit = std::numeric_limits<double>::infinity();
/// The largest whole number a command line takes (ArgParser's bound before the table).
constexpr double kMaxWhole = 1e9;

template <typename T>
struct MemberOf;
template <typename C, typename T>
struct MemberOf<T C::*> {
  using Class = C;
  using Type = T;
};

template <auto Member>
using ClassOf = typename MemberOf<decltype(Member)>::Class;
template <auto Member>
using TypeOf = typename MemberOf<decltype(Member)>::Type;

template <auto Member>
SettingValue getField(const ClassOf<Member>& object) {
  return SettingValue(object.*Member);
}

template <auto Member>
void setField(ClassOf<Member>& object, const SettingValue& value) {
  object.*Member = std::get<TypeOf<Member>>(value);
}

/// The member `Inner` of the member `Outer` (DatabaseBuildOptions::model's PoseModelOptions).
template <auto Outer, auto Inner>
SettingValue getNestedField(const ClassOf<Outer>& object) {
  return SettingValue((object.*Outer).*Inner);
}

template <auto Outer, auto Inner>
void setNestedField(ClassOf<Outer>& object, const SettingValue& value) {
  (object.*Outer).*Inner = std::get<TypeOf<Inner>>(value);
}

bool sameChoice(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) {
    return false;
  }
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(a[i])) !=
        std::tolower(static_cast<unsigned char>(b[i]))) {
      return false;
    }
  }
  return true;
}

template <auto Member, auto Name>
SettingValue getChoice(const ClassOf<Member>& object) {
  return std::string(Name(object.*Member));
}

/// Enum values 0 .. Count-1 are the choices, spelled by Name (checked before: it is one).
template <auto Member, auto Name, int Count>
void setChoice(ClassOf<Member>& object, const SettingValue& value) {
  using Mode = TypeOf<Member>;
  for (int i = 0; i < Count; ++i) {
    if (sameChoice(std::get<std::string>(value), Name(static_cast<Mode>(i)))) {
      object.*Member = static_cast<Mode>(i);
      return;
    }
  }
  DS_THROW(kInternal, "setChoice: '", std::get<std::string>(value), "' was not checked");
}

/// Builds one row of the table in place (rows are declared as one chain each, below).
class Row {
 public:
  Row(std::vector<SettingRow>& rows, const char* key, const char* label, SettingType type,
      SettingScope scope = SettingScope::kEvaluator)
      : mRow(rows.emplace_back()) {
    mRow.setting.key = key;
    mRow.setting.label = label;
    mRow.setting.type = type;
    mRow.setting.scope = scope;
  }
  Row& flag(const char* name, const char* valueName = nullptr) {
    mRow.setting.flag = name;
    mRow.setting.valueName = valueName;
    return *this;
  }
  Row& range(double minimum, double maximum, const char* unit = "", const char* zero = "") {
    mRow.setting.minimum = minimum;
    mRow.setting.maximum = maximum;
    mRow.setting.unit = unit;
    mRow.setting.zero = zero;
    return *this;
  }
  Row& help(const char* text) {
    mRow.setting.help = text;
    return *this;
  }
  Row& usedWhen(bool (*used)(const SettingsView&), const char* words, WhenUnused policy) {
    mRow.setting.used = used;
    mRow.setting.usedWhen = words;
    mRow.setting.whenUnused = policy;
    return *this;
  }
  /// The report's settings hold the value under `key` (and its schema says so).
  Row& report(const char* key) {
    mRow.setting.reportKey = key;
    mRow.report.push_back({key});
    return *this;
  }
  /// An entry of the report's settings that a describe function or a stage writes (for the
  /// schema only): `schema` as JSON text where the row's type does not give it.
  Row& reportsAlso(const char* path, const char* schema = nullptr, bool required = true) {
    mRow.report.push_back({path, schema, required});
    return *this;
  }
  /// The report names what `choice` resolved to, never `choice` itself.
  Row& reportResolves(const char* choice) {
    mRow.reportResolves = choice;
    return *this;
  }
  /// Words that stand for values (model_history's auto).
  Row& words(std::vector<std::pair<std::string, double>> list) {
    mRow.setting.words = std::move(list);
    return *this;
  }
  /// The check beyond the range, and what the setting then takes, in words.
  Row& takes(const char* text, bool (*accepts)(const SettingValue&)) {
    mRow.setting.takes = text;
    mRow.setting.accepts = accepts;
    return *this;
  }
  // ---- The Blender add-on (AddonView) ----
  /// Shown in the add-on's `panel`, named `name` (nullptr: the label in Title Case), its row
  /// saying `text` (nullptr: the name).
  Row& addon(const char* panel, const char* name = nullptr, const char* text = nullptr) {
    mRow.addon.panel = panel;
    mRow.addon.name = name;
    mRow.addon.text = text;
    return *this;
  }
  /// A checkbox's heading in its panel.
  Row& addonHeading(const char* heading) {
    mRow.addon.heading = heading;
    return *this;
  }
  /// The property's name where it is not the key (saved .blend files use it).
  Row& addonProperty(const char* name) {
    mRow.addon.property = name;
    return *this;
  }
  /// Greyed out while the kBool setting `key` is off.
  Row& addonActiveWith(const char* key) {
    mRow.addon.activeWith = key;
    return *this;
  }
  /// A two-choice setting shown as a checkbox that means `choice` when on.
  Row& addonCheckbox(const char* choice) {
    mRow.addon.checkbox = choice;
    return *this;
  }
  /// A number's slider: its end, the digits shown and Blender's step (0: Blender's).
  Row& addonSlider(double softMaximum, int precision = -1, double step = 0) {
    mRow.addon.softMaximum = softMaximum;
    mRow.addon.precision = precision;
    mRow.addon.step = step;
    return *this;
  }
  /// The menu of a choice, in the order of the numbers .blend files store.
  Row& addonChoices(std::vector<AddonChoice> choices) {
    mRow.addon.choices = std::move(choices);
    return *this;
  }
  /// The add-on's default where it is not the table's, and why.
  Row& addonDefault(const SettingValue& value, const char* why) {
    mRow.addon.defaultValue = value;
    mRow.addon.defaultWhy = why;
    return *this;
  }
  Row& describe(void (*fn)(const Model&, nlohmann::json&)) {
    mRow.describe = fn;
    return *this;
  }
  Row& describeBake(void (*fn)(const BakeOptions&, nlohmann::json&)) {
    mRow.describeBake = fn;
    return *this;
  }
  Row& hash(void (*fn)(const HashInput&, Hasher&)) {
    mRow.setting.hashed = true;
    mRow.hash = fn;
    return *this;
  }
  Row& hashAfterVersion(std::uint64_t (*fn)(const HashInput&, std::uint64_t)) {
    mRow.setting.hashed = true;
    mRow.hashAfterVersion = fn;
    return *this;
  }
  /// The value is the member `Member` of EvaluatorSettings, BakeOptions, LayerOptions,
  /// DatabaseBuildOptions or SimulationOptions.
  template <auto Member>
  Row& field() {
    return access<ClassOf<Member>>(&getField<Member>, &setField<Member>);
  }
  /// The value is the member `Inner` of the member `Outer`.
  template <auto Outer, auto Inner>
  Row& field() {
    return access<ClassOf<Outer>>(&getNestedField<Outer, Inner>, &setNestedField<Outer, Inner>);
  }
  /// The spellings of a kChoice whose value is not an enum (access() reads and writes it).
  Row& choices(std::vector<std::string> spellings) {
    mRow.setting.choices = std::move(spellings);
    return *this;
  }
  /// The value is the enum member `Member`, spelled by `Name`, of `Count` values 0 .. Count-1.
  template <auto Member, auto Name, int Count>
  Row& choice() {
    for (int i = 0; i < Count; ++i) {
      mRow.setting.choices.emplace_back(Name(static_cast<TypeOf<Member>>(i)));
    }
    return access<ClassOf<Member>>(&getChoice<Member, Name>, &setChoice<Member, Name, Count>);
  }
  /// The value through `get` and `set` (nullptr: read-only) of EvaluatorSettings, BakeOptions,
  /// LayerOptions, DatabaseBuildOptions or SimulationOptions.
  template <typename Class>
  Row& access(SettingValue (*get)(const Class&), void (*set)(Class&, const SettingValue&)) {
    if constexpr (std::is_same_v<Class, EvaluatorSettings>) {
      mRow.setting.getEvaluator = get;
      mRow.setting.setEvaluator = set;
    } else if constexpr (std::is_same_v<Class, BakeOptions>) {
      mRow.setting.getBake = get;
      mRow.setting.setBake = set;
    } else if constexpr (std::is_same_v<Class, LayerOptions>) {
      mRow.setting.getLayer = get;
      mRow.setting.setLayer = set;
    } else if constexpr (std::is_same_v<Class, DatabaseBuildOptions>) {
      mRow.setting.getBuild = get;
      mRow.setting.setBuild = set;
    } else {
      static_assert(std::is_same_v<Class, SimulationOptions>);
      mRow.setting.getSimulate = get;
      mRow.setting.setSimulate = set;
    }
    return *this;
  }

 private:
  SettingRow& mRow;
};

// ---- When settings are used (WeightMode::kAuto counts as each mode it may become) -----------

bool mayRunQp(const SettingsView& v) {
  return v.evaluator.weightMode == WeightMode::kQp || v.evaluator.weightMode == WeightMode::kAuto;
}
bool mayRunModel(const SettingsView& v) {
  const WeightMode mode = v.evaluator.weightMode;
  return mode == WeightMode::kModel || mode == WeightMode::kAuto;
}
bool mayAlign(const SettingsView& v) {
  const WeightMode mode = v.evaluator.weightMode;
  return mode != WeightMode::kModel && mode != WeightMode::kBind;
}
bool bindsMasked(const SettingsView& v) {
  return v.evaluator.correct && v.evaluator.weightMode != WeightMode::kModel;
}
bool alignsOnGroup(const SettingsView& v) {
  const std::string& group = v.evaluator.alignGroup;
  return group.empty() || group == "all" || (mayAlign(v) && v.evaluator.align != AlignMode::kNone);
}
bool blendUsed(const SettingsView& v) {
  // World blending is what runs without the correction or with the bind baseline.
  return v.evaluator.blend == BlendMode::kWorld ||
         (v.evaluator.correct && v.evaluator.weightMode != WeightMode::kBind);
}
bool resolves(const SettingsView& v) {
  return v.evaluator.resolve;
}
bool searchesClosest(const SettingsView& v) {
  return v.evaluator.resolve || v.evaluator.audit;
}
bool boundsWeights(const SettingsView& v) {
  return v.evaluator.maxWeightChange > 0;
}
bool limitsStrain(const SettingsView& v) {
  return v.evaluator.strainLimit > 0;
}
bool zips(const SettingsView& v) {
  return v.bake == nullptr || v.bake->compression == ExrCompression::kZip ||
         v.bake->compression == ExrCompression::kZips;
}

// ---- Hash entries (the layout of 0.1's EXR headers: see hashSettings) ---------------------

void hashWeightMode(const HashInput& in, Hasher& h) {
  h.addValue(static_cast<int>(in.model.settings.weightMode));
}
void hashExrWidth(const HashInput& in, Hasher& h) {
  if (in.output != nullptr) {
    h.addValue(in.output->exrWidth);
  }
}
void hashCorrect(const HashInput& in, Hasher& h) {
  h.addValue(in.model.settings.correct);
}
void hashMask(const HashInput& in, Hasher& h) {
  const BindingMask& mask = in.model.mask();
  for (int c = 0; c < mask.classCount(); ++c) {
    h.add(mask.classTriangles(c).data(), mask.classTriangles(c).size() * sizeof(int));
  }
  h.add(mask.vertexClasses().data(), mask.vertexClasses().size() * sizeof(int));
}
void hashAlign(const HashInput& in, Hasher& h) {
  h.addValue(static_cast<int>(in.model.settings.align));
}
/// The vertices the group selects and the weights the alignment gives them.
void hashAlignGroup(const HashInput& in, Hasher& h) {
  h.add(in.model.alignVertices.data(), in.model.alignVertices.size() * sizeof(int));
  if (in.model.aligner) {
    const auto& weights = in.model.aligner->weights();
    h.add(weights.data(), weights.size() * sizeof(double));
  }
}
/// The blend that runs (blendsLocally), not the one asked for.
void hashBlend(const HashInput& in, Hasher& h) {
  h.addValue(in.model.local);
}
void hashResolve(const HashInput& in, Hasher& h) {
  h.addValue(in.model.settings.resolve);
}
void hashSkinOffset(const HashInput& in, Hasher& h) {
  h.addValue(in.model.settings.resolve ? in.model.settings.skinOffset : 0.0);
}
/// Along the normal, the resolution leaves the hash of the bakes before the nearest direction.
void hashResolveDirection(const HashInput& in, Hasher& h) {
  if (in.model.settings.resolve &&
      in.model.settings.resolveDirection != ResolveDirection::kNormal) {
    h.addValue(static_cast<int>(in.model.settings.resolveDirection));
  }
}
/// Off, the exit fade leaves the hash of the bakes before it.
void hashExitFade(const HashInput& in, Hasher& h) {
  if (in.model.settings.resolve && in.model.settings.exitFade > 0) {
    h.addValue(in.model.settings.exitFade);
  }
}
void hashRegions(const HashInput& in, Hasher& h) {
  const std::optional<RegionSet>& regions = in.model.settings.regions;
  h.addValue(regions.has_value());
  if (regions) {
    h.addValue(regions->falloff);
    for (const Region& region : regions->regions) {
      h.add(region.driverVertices.data(), region.driverVertices.size() * sizeof(int));
      h.add(region.drivenVertices.data(), region.drivenVertices.size() * sizeof(int));
    }
  }
}
void hashMaxWeightChange(const HashInput& in, Hasher& h) {
  h.addValue(in.model.settings.maxWeightChange);
}
/// With the temporal bound, the warm-up and the batch decide which frame bounds which.
void hashTemporalWarmup(const HashInput& in, Hasher& h) {
  if (in.output != nullptr && in.model.settings.maxWeightChange > 0) {
    h.addValue(in.output->temporalWarmup);
  }
}
void hashBatch(const HashInput& in, Hasher& h) {
  if (in.output != nullptr && in.model.settings.maxWeightChange > 0) {
    h.addValue(in.output->batchSize);
  }
}
/// Off, the strain limit leaves the hash of the bakes before it. On, marks of its method
/// (src/pipeline/stages/strain_limit.cpp), so that no bake of the limit before it is taken for
/// one now: the garment's open borders held (2: with no momentum from their skin planes' push,
/// where 1 let them drift by up to 0.005 mm); with the resolution, the cloth kept in front of
/// its skin planes (2: the planes reach 2 skin offsets, where 1 gave them to every vertex the
/// certificate searched; 3: the settle stage after the resolution).
void hashStrainLimit(const HashInput& in, Hasher& h) {
  if (in.model.settings.strainLimit > 0) {
    h.addValue(in.model.settings.strainLimit);
    constexpr std::int32_t kHeldBorders = 2;
    h.addValue(kHeldBorders);
    // The gain of the corrections that lengthen a short edge (src/pipeline/stages/
    // strain_limit.cpp: 0.5; none in the hash meant 1).
    constexpr std::int32_t kHalfCompression = 1;
    h.addValue(kHalfCompression);
    if (in.model.settings.resolve) {
      constexpr std::int32_t kSkinPlanes = 3;
      h.addValue(kSkinPlanes);
    }
  }
}
/// With the limit, its iterations and a mark of their acceleration (the first Chebyshev-
/// accelerated iteration, src/pipeline/stages/strain_limit.cpp: 2; none in the hash meant 5).
void hashStrainIterations(const HashInput& in, Hasher& h) {
  if (in.model.settings.strainLimit > 0) {
    h.addValue(in.model.settings.strainIterations);
    constexpr std::int32_t kAcceleratedFrom = 2;
    h.addValue(kAcceleratedFrom);
  }
}
std::uint64_t hashLayers(const HashInput& in, std::uint64_t value) {
  if (!in.model.layerStack) {
    return value;
  }
  Hasher layers;
  layers.addValue(value);
  in.model.layerStack->addToHash(layers);
  return layers.value();
}

// ---- Report entries that are not the plain value --------------------------------------------

/// The report's regions: what the weights stage found for each region it ran.
constexpr const char* kRegionsSchema = R"({
  "type": "array",
  "items": {
    "type": "object",
    "additionalProperties": false,
    "required": ["name", "driver_vertices", "driven_vertices"],
    "properties": {
      "name": {"type": "string"},
      "driver_vertices": {"$ref": "#/$defs/count"},
      "driven_vertices": {"$ref": "#/$defs/count"}
    }
  }
})";

void describeAlignGroup(const Model& model, nlohmann::json& out) {
  const std::string& group = model.settings.alignGroup;
  out["align_group"] = group.empty() ? std::string("all") : group;
  out["align_vertices"] = 0;  // the align stage writes the count where it runs
}
void describeBlend(const Model& model, nlohmann::json& out) {
  out["blend"] = blendModeName(model.local ? BlendMode::kLocal : BlendMode::kWorld);
}
void describeRegions(const Model&, nlohmann::json& out) {
  out["regions"] = nlohmann::json::array();  // the weights stage lists them where they run
  out["region_falloff"] = 0;
}
void describeLayers(const Model&, nlohmann::json& out) {
  out["layers"] = nlohmann::json::object();  // the layers stage describes them
}
void describeMaskFile(const BakeOptions& options, nlohmann::json& out) {
  out["binding_mask"] = options.bindingMaskPath;
}
void describeRegionsFile(const BakeOptions& options, nlohmann::json& out) {
  out["regions_file"] = options.regionsPath;
}
void describeTemporalWarmup(const BakeOptions& options, nlohmann::json& out) {
  out["temporal_warmup"] = options.evaluator.maxWeightChange > 0 ? options.temporalWarmup : 0;
}

// ---- Accessors that are not one member -------------------------------------------------------

SettingValue maskText(const EvaluatorSettings& s) {
  return std::string(s.bindingMask ? "(a binding mask)" : "");
}
SettingValue regionsText(const EvaluatorSettings& s) {
  return std::string(s.regions ? "(a region set)" : "");
}
SettingValue layersText(const EvaluatorSettings& s) {
  return std::string(s.layers.empty() ? "" : "(layers)");
}
/// The bake's threads are BakeOptions::threads (the evaluator's are set from them).
SettingValue bakeThreads(const BakeOptions& o) {
  return o.threads;
}
void setBakeThreads(BakeOptions& o, const SettingValue& value) {
  o.threads = o.evaluator.threads = std::get<int>(value);
}
/// The wind's direction as X,Y,Z (its command-line form).
SettingValue windDirectionText(const LayerOptions& o) {
  std::string text;
  for (const double value : o.windDirection) {
    text += (text.empty() ? "" : ",") + formatSettingValue(value);
  }
  return text;
}
void setWindDirection(LayerOptions& o, const SettingValue& value) {
  const std::string& text = std::get<std::string>(value);
  std::array<double, 3> direction{};
  std::stringstream stream(text);
  std::string part;
  int count = 0;
  while (std::getline(stream, part, ',')) {
    char* end = nullptr;
    errno = 0;
    const double number = std::strtod(part.c_str(), &end);
    if (count >= 3 || part.empty() || *end != '\0' || errno != 0 || !std::isfinite(number)) {
      count = -1;
      break;
    }
    direction[static_cast<std::size_t>(count++)] = number;
  }
  if (count != 3) {
    DS_THROW(kUsage,
             "the wind direction (wind_direction, --wind-direction) takes X,Y,Z, three "
             "numbers (got '",
             text, "')");
  }
  o.windDirection = direction;
}
SettingValue windSeed(const LayerOptions& o) {
  return static_cast<int>(o.windSeed);
}
void setWindSeed(LayerOptions& o, const SettingValue& value) {
  o.windSeed = static_cast<std::uint32_t>(std::get<int>(value));
}
SettingValue poseModelChoice(const DatabaseBuildOptions& o) {
  return std::string(o.poseModel ? "pose" : "none");
}
void setPoseModelChoice(DatabaseBuildOptions& o, const SettingValue& value) {
  o.poseModel = sameChoice(std::get<std::string>(value), "pose");
}
/// model_parts: one part is no joint to read.
bool notOnePart(const SettingValue& value) {
  return std::get<int>(value) != 1;
}
/// verdict_level: a share below 1 (every frame is no level to calibrate to).
bool belowOne(const SettingValue& value) {
  return std::get<double>(value) < 1.0;
}

// ---- The table ------------------------------------------------------------------------------
// Rows in the order of the settings hash (a file-format contract: never reorder hashed rows),
// then those it does not hash. Each row is the one declaration of its setting.

void weightAndAlignmentRows(std::vector<SettingRow>& rows) {
  using S = EvaluatorSettings;
  Row(rows, "weight_mode", "weights", SettingType::kChoice)
      .flag("--weights", "MODE")
      .choice<&S::weightMode, &weightModeName, 5>()
      .help(
          "auto (model when the database has a pose model and the settings fit it, else qp), "
          "model (the rest binding plus the pose model's learned correction), qp (the 2008 "
          "DrivenShape blend); baselines: nearest (the closest database shape), bind (the rest "
          "cloth bound to the rest driver and carried along, like Point Deform)")
      .hash(&hashWeightMode)
      .report("weights")
      .reportResolves("auto")
      .addon("settings")
      .addonChoices(
          {{"auto", "Auto", "The pose model when the database has one, else the DrivenShape QP"},
           {"model", "Pose Model",
            "The rest binding plus the pose model's learned correction, fitted over the whole "
            "reference clip"},
           {"qp", "QP Blend",
            "DrivenShape as in the talk: blend weights that best reproduce the pose (a QP)"},
           {"nearest", "Nearest", "Baseline: all weight on the closest database driver shape"},
           {"bind", "Bind Only",
            "Baseline: no database shapes; the rest cloth carried by the driver"}});
  Row(rows, "exr_width", "EXR width", SettingType::kInt, SettingScope::kBake)
      .flag("--exr-width", "W")
      .field<&BakeOptions::exrWidth>()
      .range(1, kMaxPointCacheExrWidth, "pixels")
      .help("pixels per EXR row (vertex v is pixel v mod W, v div W)")
      .hash(&hashExrWidth)
      .report("exr_width");
  Row(rows, "correct", "collision correction", SettingType::kBool)
      .flag("--no-correct")
      .field<&S::correct>()
      .help("the collision correction: carry the blended cloth onto the shot's driver")
      .hash(&hashCorrect)
      .report("correct")
      .addon("collision", nullptr, "Correction")
      .addonHeading("Collision");
  Row(rows, "binding_mask", "binding mask", SettingType::kObject)
      .flag("--bind", "MAP.json")
      .access<EvaluatorSettings>(&maskText, nullptr)
      .field<&BakeOptions::bindingMaskPath>()
      .help(
          "which driver triangles each cloth vertex may bind to (a JSON file: "
          "readBindingMask; Python: load_binding_mask); none = every triangle")
      .usedWhen(&bindsMasked,
                "with the correction and the qp, nearest or bind weights (the pose model was "
                "fitted on the binding to every triangle)",
                WhenUnused::kRefuse)
      .hash(&hashMask)
      .describeBake(&describeMaskFile)
      .reportsAlso("binding_mask");
  Row(rows, "align", "alignment", SettingType::kChoice)
      .flag("--align", "MODE")
      .choice<&S::align, &alignModeName, 3>()
      .help(
          "none (the talk: weights compare world positions), rigid (each shot frame and "
          "database shape is first fitted rigidly to the rest driver, weighted by how "
          "rigidly each vertex moves across the database: the pelvis, not the legs) or "
          "rigid-all (the same fit, every vertex weighted by its area alone)")
      .usedWhen(&mayAlign, "with the qp or nearest weights", WhenUnused::kWarn)
      .hash(&hashAlign)
      .report("align")
      .addon("settings", "Align")
      .addonChoices(
          {{"rigid", "Rigid",
            "Fit each frame rigidly to the rest driver, following its most rigid part "
            "(the pelvis, not the legs) before solving the weights"},
           {"rigid-all", "Rigid (All)", "The same rigid fit, every vertex weighted alike"},
           {"none", "None", "Compare world positions, as in the talk"}});
  Row(rows, "align_group", "align group", SettingType::kText)
      .flag("--align-group", "LIST")
      .field<&S::alignGroup>()
      .help(
          "driver vertices of the rigid fit: comma-separated OBJ group names and/or vertex "
          "indices and ranges (0-99,250); empty or all = every vertex")
      .usedWhen(&alignsOnGroup,
                "with an alignment (align rigid or rigid-all) and the qp or "
                "nearest weights",
                WhenUnused::kRefuse)
      .hash(&hashAlignGroup)
      .describe(&describeAlignGroup)
      .reportsAlso("align_group", R"({"type": "string", "minLength": 1})")
      .reportsAlso("align_vertices", R"({"$ref": "#/$defs/count"})");
}

void correctionRows(std::vector<SettingRow>& rows) {
  using S = EvaluatorSettings;
  Row(rows, "blend", "blend", SettingType::kChoice)
      .flag("--blend", "MODE")
      .choice<&S::blend, &blendModeName, 2>()
      .help(
          "world (blend world positions, then correct) or local (bind every cloth vertex "
          "once at rest, blend the shapes' offsets in those local frames, rebuild them on the "
          "shot's driver: that is the correction)")
      .usedWhen(&blendUsed,
                "with the correction and weights other than bind (which blend world "
                "positions)",
                WhenUnused::kRefuse)
      .hash(&hashBlend)
      .describe(&describeBlend)
      .reportsAlso("blend")
      .addon("settings")
      .addonChoices(
          {{"local", "Local Frames",
            "Blend the shapes' offsets in the driver's local frames and rebuild them on "
            "the current pose (no per-frame search)"},
           {"world", "World", "Blend world positions, then correct onto the pose (the talk)"}});
  Row(rows, "resolve", "penetration resolution", SettingType::kBool)
      .flag("--no-resolve")
      .field<&S::resolve>()
      .help(
          "the penetration resolution: cloth inside the driver or closer than the skin "
          "offset moves out to the offset")
      .hash(&hashResolve)
      .report("resolve")
      .addon("collision", nullptr, "Penetrations")
      .addonHeading("Resolve");
  Row(rows, "skin_offset", "skin offset", SettingType::kNumber)
      .flag("--skin-offset", "D")
      .field<&S::skinOffset>()
      .range(0, kMaxCoordinate, "scene units")
      .help(
          "penetration resolution: cloth closer to the driver than this distance (or inside "
          "it) moves out to it (0.002 = 2 mm in metre scenes)")
      .usedWhen(&resolves, "with the penetration resolution (resolve)", WhenUnused::kWarn)
      .hash(&hashSkinOffset)
      .report("skin_offset")
      .addon("collision", nullptr, "Offset")
      .addonActiveWith("resolve")
      .addonSlider(0.05, 4, 0.01);
  Row(rows, "resolve_direction", "resolve direction", SettingType::kChoice)
      .flag("--resolve-direction", "DIR")
      .choice<&S::resolveDirection, &resolveDirectionName, 2>()
      .help(
          "penetration resolution: nearest (a vertex within the offset on its own side of the "
          "skin moves along the line from its closest point on the driver, the shortest way; "
          "one on the wrong side along the driver's pseudo-normal) or normal (every vertex "
          "along the pseudo-normal, as 0.1 did: where the closest point crosses from a face "
          "onto an edge the cloth jumps by up to half the angle between the two faces)")
      .usedWhen(&resolves, "with the penetration resolution (resolve)", WhenUnused::kWarn)
      .hash(&hashResolveDirection)
      .report("resolve_direction")
      .addon("collision", nullptr, "Direction")
      .addonActiveWith("resolve")
      .addonChoices({{"nearest", "Nearest",
                      "Cloth within the offset moves along the line from its closest point on the "
                      "driver (smooth where that point crosses an edge); cloth inside along the "
                      "normal"},
                     {"normal", "Normal",
                      "Every vertex moves along the driver's normal at its closest point (0.1; "
                      "jumps where that point crosses from a face onto an edge)"}});
  Row(rows, "exit_fade", "exit fade", SettingType::kNumber)
      .flag("--exit-fade", "K")
      .field<&S::exitFade>()
      .range(0, kNoLimit, "", "off, always all the way")
      .help(
          "penetration resolution: a vertex deep inside the body whose two nearest exits "
          "differ by at most this factor times its depth moves only part of the way, none "
          "where they tie, so cloth caught in a limb or a bent joint does not jump across it "
          "between frames (0.25 with the strain limit, 0.15 without it: the validation's "
          "best)")
      .usedWhen(&resolves, "with the penetration resolution (resolve)", WhenUnused::kWarn)
      .hash(&hashExitFade)
      .report("exit_fade")
      .addon("collision")
      .addonActiveWith("resolve")
      .addonSlider(1.0, 2, 1);
  Row(rows, "regions", "regions", SettingType::kObject)
      .flag("--regions", "FILE.json")
      .access<EvaluatorSettings>(&regionsText, nullptr)
      .field<&BakeOptions::regionsPath>()
      .help(
          "region-local weights: one QP per region (driver groups) mixed over the matching "
          "driven groups with a smooth falloff (a JSON file: readRegions; Python: "
          "load_regions); none = one QP on every driver row")
      .usedWhen(&mayRunQp, "with the qp weights", WhenUnused::kRefuse)
      .hash(&hashRegions)
      .describe(&describeRegions)
      .describeBake(&describeRegionsFile)
      .reportsAlso("regions", kRegionsSchema)
      .reportsAlso("region_falloff", R"({"type": "number", "minimum": 0})")
      .reportsAlso("regions_file");
  Row(rows, "max_weight_change", "maximum weight change", SettingType::kNumber)
      .flag("--max-weight-change", "TAU")
      .field<&S::maxWeightChange>()
      .range(0, 1, "", "off")
      .help(
          "temporal stability: no shape's weight changes by more than this between "
          "consecutive frames (|w_t - w_{t-1}|), frames solved in order within each batch")
      .usedWhen(&mayRunQp, "with the qp weights", WhenUnused::kRefuse)
      .hash(&hashMaxWeightChange)
      .report("max_weight_change")
      .addon("settings", "Temporal Bound", "Temporal")
      .addonSlider(kNoLimit, 3, 1);
}

void batchAndLayerRows(std::vector<SettingRow>& rows) {
  using S = EvaluatorSettings;
  Row(rows, "temporal_warmup", "temporal warm-up", SettingType::kInt, SettingScope::kBake)
      .flag("--temporal-warmup", "N")
      .field<&BakeOptions::temporalWarmup>()
      .range(0, kNoLimit, "frames")
      .help(
          "with a maximum weight change: driver-cache frames solved, not written, before "
          "each batch; results depend on N and the batch, not on the threads")
      .usedWhen(&boundsWeights, "with a maximum weight change", WhenUnused::kWarn)
      .hash(&hashTemporalWarmup)
      .describeBake(&describeTemporalWarmup)
      .reportsAlso("temporal_warmup");
  Row(rows, "batch", "batch", SettingType::kInt, SettingScope::kBake)
      .flag("--batch", "N")
      .field<&BakeOptions::batchFrames>()
      .range(1, kNoLimit, "frames")
      .help(
          "frames per kernel launch (bounds device memory; lowered for large meshes except "
          "with a maximum weight change, whose results depend on it)")
      .hash(&hashBatch)
      .report("batch");
  Row(rows, "strain_limit", "strain limit", SettingType::kNumber)
      .flag("--strain-limit", "S")
      .field<&S::strainLimit>()
      .range(0, 0.5, "", "off")
      .help(
          "after the correction and before the penetration resolution, each frame's cloth "
          "edges are brought back within this fraction of their rest lengths (0.01: 99% to "
          "101%) by iterations of edge projections, the garment's open borders (hems, cuffs) "
          "held where they are, so the cloth does not stretch like rubber; with the "
          "resolution on, the cloth is kept out of the body while it iterates, and what the "
          "resolution leaves shallowly inside comes just out after it (turned off, give "
          "--exit-fade 0.15 with it: the validation's best without the limit)")
      .hash(&hashStrainLimit)
      .addon("collision", nullptr, "Strain Limit")
      .report("strain_limit");
  Row(rows, "strain_iterations", "strain iterations", SettingType::kInt)
      .flag("--strain-iterations", "N")
      .field<&S::strainIterations>()
      .range(1, 10000, "iterations")
      .help(
          "strain limit: Chebyshev-accelerated Jacobi iterations per frame, each one pass over "
          "the edges (more: edges closer to the band)")
      .usedWhen(&limitsStrain, "with a strain limit (strain_limit above 0)", WhenUnused::kWarn)
      .hash(&hashStrainIterations)
      .addon("collision", nullptr, "Iterations")
      .report("strain_iterations");
  Row(rows, "layers", "layers", SettingType::kObject)
      .access<EvaluatorSettings>(&layersText, nullptr)
      .help(
          "layers after the correction and the resolution: a mix with another cache, wind "
          "(command line: the --mix and --wind-* options, see Layer options; Python: "
          "load_layers); none by default")
      .hashAfterVersion(&hashLayers)
      .describe(&describeLayers)
      .reportsAlso("layers");
  Row(rows, "audit", "audit", SettingType::kBool)
      .flag("--no-audit")
      .field<&S::audit>()
      .help(
          "the per-frame audit: cloth vertices inside the driver before and after the "
          "correction, binding switches, the largest frame-to-frame jump (costs time)")
      .report("audit")
      .addon("device")
      .addonDefault(false,
                    "live mode evaluates every frame the animator scrubs to; the audit costs time "
                    "there and its counts are only shown when asked for");
  Row(rows, "coverage_tolerance", "coverage tolerance", SettingType::kNumber)
      .flag("--coverage-tolerance", "D")
      .field<&S::coverageTolerance>()
      .range(0, kNoLimit, "scene units", "2% of the cloth's rest bounding-box diagonal")
      .help(
          "pose model: frames whose error bound (the predicted mean vertex error, scaled to "
          "hold on the database's verdict level of frames) exceeds this distance are flagged "
          "for simulation")
      .usedWhen(&mayRunModel, "with the pose model (weights model)", WhenUnused::kWarn)
      // The model stage writes the tolerance it used (the default resolved), with the model.
      .reportsAlso("coverage_tolerance", R"({"$ref": "#/$defs/positive_length"})", false)
      .addon("coverage", nullptr, "Tolerance")
      .addonSlider(0.1, 4, 0.1);
}

void runRows(std::vector<SettingRow>& rows) {
  using S = EvaluatorSettings;
  Row(rows, "threads", "threads", SettingType::kInt)
      .flag("--threads", "N")
      .field<&S::threads>()
      .access<BakeOptions>(&bakeThreads, &setBakeThreads)
      .range(0, kNoLimit, "", "all cores")
      .help(
          "host threads for the weights, the alignment, the closest-point search and EXR "
          "writing")
      .addon("device")
      .addonSlider(64);
  Row(rows, "clearance_certificate", "clearance certificate", SettingType::kBool)
      .field<&S::clearanceCertificate>()
      .help(
          "search closest points only where they can matter (the cloth and every count are "
          "bitwise the same either way; off only to measure or check the full search)")
      .usedWhen(&searchesClosest, "with the penetration resolution or the audit",
                WhenUnused::kWarn);
  Row(rows, "compression", "EXR compression", SettingType::kChoice, SettingScope::kBake)
      .flag("--compression", "C")
      .choice<&BakeOptions::compression, &exrCompressionName, 4>()
      .help("EXR compression, all lossless")
      .report("compression");
  Row(rows, "zip_encoder", "zip encoder", SettingType::kChoice, SettingScope::kBake)
      .flag("--zip-encoder", "E")
      .choice<&BakeOptions::zipEncoder, &zipEncoderName, 2>()
      .help(
          "who deflates zip and zips files (standard files either way): libdeflate, or "
          "openexr (OpenEXR's zlib writer, 2-4x the CPU: the bytes of earlier builds)")
      .usedWhen(&zips, "with zip or zips compression", WhenUnused::kWarn);
  Row(rows, "frames_per_second", "frames per second", SettingType::kNumber, SettingScope::kBake)
      .flag("--fps", "X")
      .field<&BakeOptions::framesPerSecond>()
      .field<&LayerOptions::framesPerSecond>()
      .range(1e-3, kNoLimit)
      .help("written to the EXR headers; the wind's time is frame / X")
      .reportsAlso("layers.wind.fps");
}

/// The layers' options (LayerOptions; BakeOptions::layers): not hashed one by one, the layers
/// row hashes what they load. LayerStack checks how they go together.
void mixRows(std::vector<SettingRow>& rows) {
  using L = LayerOptions;
  const SettingScope layer = SettingScope::kLayer;
  Row(rows, "mix_cache", "mix cache", SettingType::kText, layer)
      .flag("--mix", "CACHE")
      .field<&L::mixCache>()
      .help(
          "mix the result per vertex with another cache of the driven mesh (a simulated hood, a "
          "skinned mesh): .pc2 or name.####.exr, every baked frame present; empty: no mix")
      .reportsAlso("layers.mix.cache");
  Row(rows, "mix_weight", "mix weight map", SettingType::kText, layer)
      .flag("--mix-weight", "MAP")
      .field<&L::mixWeight>()
      .help(
          "w of out = w DrivenShape + (1 - w) mix cache per vertex, 1 keeping the DrivenShape "
          "result: a .json array with one number in [0, 1] per driven vertex, a one-channel "
          "point-cache .exr, or group:NAME[,NAME] (faces of the driven OBJ's groups); needed "
          "with a mix cache")
      .reportsAlso("layers.mix.weight");
  Row(rows, "mix_falloff", "mix falloff", SettingType::kInt, layer)
      .flag("--mix-falloff", "RINGS")
      .field<&L::mixFalloff>()
      .range(0, 64, "edge rings", "hard edge")
      .help("soften the mix weight map's edge across this many edge rings")
      .reportsAlso("layers.mix.falloff");
}

void windRows(std::vector<SettingRow>& rows) {
  using L = LayerOptions;
  const SettingScope layer = SettingScope::kLayer;
  Row(rows, "wind_amplitude", "wind amplitude", SettingType::kNumber, layer)
      .flag("--wind-amplitude", "UNITS")
      .field<&L::windAmplitude>()
      .range(0, kNoLimit, "scene units", "no wind")
      .help("procedural wind: the largest displacement per axis")
      .reportsAlso("layers.wind.amplitude");
  Row(rows, "wind_frequency", "wind frequency", SettingType::kNumber, layer)
      .flag("--wind-frequency", "PER_UNIT")
      .field<&L::windFrequency>()
      .range(0, kNoLimit)
      .help("noise cells per scene unit of the first octave (1/size of the largest gusts)")
      .reportsAlso("layers.wind.frequency");
  Row(rows, "wind_direction", "wind direction", SettingType::kText, layer)
      .flag("--wind-direction", "X,Y,Z")
      .access<L>(&windDirectionText, &setWindDirection)
      .help("the direction the gusts travel (normalised)")
      .reportsAlso("layers.wind.direction",
                   R"({"type": "array", "items": {"type": "number"}, "minItems": 3, )"
                   R"("maxItems": 3})");
  Row(rows, "wind_speed", "wind speed", SettingType::kNumber, layer)
      .flag("--wind-speed", "UNITS_PER_S")
      .field<&L::windSpeed>()
      .range(0, kNoLimit, "scene units per second", "a still pattern")
      .help("how fast the gusts travel")
      .reportsAlso("layers.wind.speed");
  Row(rows, "wind_octaves", "wind octaves", SettingType::kInt, layer)
      .flag("--wind-octaves", "N")
      .field<&L::windOctaves>()
      .range(1, DS_WIND_MAX_OCTAVES)
      .help("noise octaves, each twice as fine and half as strong")
      .reportsAlso("layers.wind.octaves");
  Row(rows, "wind_seed", "wind seed", SettingType::kInt, layer)
      .flag("--wind-seed", "N")
      .access<L>(&windSeed, &setWindSeed)
      .range(0, kMaxWhole)
      .help("noise seed (another seed, another wind)")
      .reportsAlso("layers.wind.seed");
  Row(rows, "wind_weight", "wind weight map", SettingType::kText, layer)
      .flag("--wind-weight", "MAP")
      .field<&L::windWeight>()
      .help("where the wind blows (1) or not (0), a weight map as the mix's; empty: everywhere")
      .reportsAlso("layers.wind.weight", nullptr, false);
  Row(rows, "wind_falloff", "wind falloff", SettingType::kInt, layer)
      .flag("--wind-falloff", "RINGS")
      .field<&L::windFalloff>()
      .range(0, 64, "edge rings", "hard edge")
      .help("soften the wind weight map's edge across this many edge rings")
      .reportsAlso("layers.wind.falloff", nullptr, false);
}

/// `db build`'s settings (DatabaseBuildOptions): the pick's.
void buildRows(std::vector<SettingRow>& rows) {
  using B = DatabaseBuildOptions;
  const SettingScope build = SettingScope::kBuild;
  Row(rows, "count", "shape count", SettingType::kInt, build)
      .flag("--count", "N")
      .field<&B::count>()
      .range(1, 100000)
      .help("shapes to keep (fewer if the clip runs out of distinct ones)")
      .addon("build", "Shapes")
      .addonProperty("build_count")
      .addonSlider(128);
  Row(rows, "duplicate_tolerance", "duplicate tolerance", SettingType::kNumber, build)
      .flag("--duplicate-tolerance", "X")
      .field<&B::duplicateTolerance>()
      .range(0, 1, "of the driver's bounding-box diagonal")
      .help("reject shapes within this share of the rest driver's diagonal (RMS) of a kept one");
  Row(rows, "model", "pose model", SettingType::kChoice, build)
      .flag("--model", "KIND")
      .choices({"pose", "none"})
      .access<B>(&poseModelChoice, &setPoseModelChoice)
      .help(
          "pose: also fit the pose model over every candidate frame (the rest binding plus a "
          "learned correction; what `bake` evaluates by default); none: the picks only")
      .addon("build", "Pose Model")
      .addonProperty("build_model")
      .addonCheckbox("pose");
}

/// `db build`'s settings of the pose model (DatabaseBuildOptions::model).
void poseModelRows(std::vector<SettingRow>& rows) {
  using B = DatabaseBuildOptions;
  using M = PoseModelOptions;
  const SettingScope build = SettingScope::kBuild;
  Row(rows, "model_parts", "model parts", SettingType::kInt, build)
      .flag("--model-parts", "N")
      .field<&B::model, &M::parts>()
      .range(0, 64, "", "as many as the clip shows")
      .takes("0 (found from the clip) or 2..64", &notOnePart)
      .help("rigid parts of the driver the pose model reads its joints from");
  Row(rows, "model_velocity", "model velocity", SettingType::kInt, build)
      .flag("--model-velocity", "N")
      .field<&B::model, &M::velocityLag>()
      .range(0, 60, "frames", "no velocity")
      .help("frames back the pose model's velocity feature looks");
  Row(rows, "model_history", "model history", SettingType::kInt, build)
      .flag("--model-history", "N")
      .field<&B::model, &M::historyFrames>()
      .range(0, 120, "frames", "no history")
      .words({{"auto", kAutoHistory}})
      .help(
          "frames the pose model's history feature averages (auto = 15 with one or two "
          "reference clips, 30 with three or more)");
  Row(rows, "model_siblings", "model sibling weight", SettingType::kNumber, build)
      .flag("--model-siblings", "W")
      .field<&B::model, &M::siblingWeight>()
      .range(0, 100, "", "off")
      .help(
          "weight of the pose model's sibling features: the relative rotation of each pair of "
          "parts with the same parent (two thighs), so the cloth between them sees both");
  Row(rows, "model_rank", "model rank", SettingType::kInt, build)
      .flag("--model-rank", "N")
      .field<&B::model, &M::rank>()
      .range(1, 4096)
      .help("basis shapes the pose model keeps");
  Row(rows, "model_per_clip", "per-clip model weight", SettingType::kNumber, build)
      .flag("--model-per-clip", "W")
      .field<&B::model, &M::clipMixtureWeight>()
      .range(0, 1000)
      .words({{"auto", kAutoClipMixture}, {"off", 0.0}})
      .help(
          "models of each reference clip mixed into the pose model's prediction by how close a "
          "pose is to each clip (W = the weight of the model over every clip): auto = with "
          "three or more clips, the weight of 10, 3 or 1 that best predicts each clip left out "
          "in turn, when at least 1% better than none; off = none");
  Row(rows, "verdict_level", "verdict level", SettingType::kNumber, build)
      .flag("--verdict-level", "P")
      .field<&B::model, &M::verdictLevel>()
      .range(0.5, 1)
      .takes("a share of frames from 0.5 to below 1, e.g. 0.9", &belowOne)
      .help(
          "share of frames the coverage verdict's error bound is calibrated to hold for "
          "(split-conformal on the held-out reference frames; bake --coverage-tolerance flags a "
          "frame whose bound is over it)");
}

/// `simulate`'s settings (SimulationOptions): the plan of the windows simulated after a bake
/// (drivenshape/simulation.h) and their splice into the baked frames. The add-on's "simulate"
/// panel shows them under properties of their own names (simulate_*), beside the bake's.
void simulateRows(std::vector<SettingRow>& rows) {
  using O = SimulationOptions;
  const SettingScope simulate = SettingScope::kSimulate;
  Row(rows, "warmup", "simulation warm-up", SettingType::kInt, simulate)
      .flag("--warmup", "N")
      .field<&O::warmup>()
      .range(0, 10000, "frames", "start at the first flagged frame")
      .help(
          "frames each window simulates before its first flagged frame (never before the "
          "shot's first frame), from the bake's cloth there, so that the cloth settles")
      .addon("simulate", "Warm-up")
      .addonProperty("simulate_warmup")
      .addonSlider(60);
  Row(rows, "merge_gap", "merge gap", SettingType::kInt, simulate)
      .flag("--merge-gap", "N")
      .field<&O::mergeGap>()
      .range(0, 10000, "frames", "only consecutive flagged frames")
      .help(
          "flagged frames at most this many unflagged frames apart are one window, the frames "
          "between handed back too (cheaper than another warm-up and two more seams)")
      .addon("simulate")
      .addonProperty("simulate_merge_gap")
      .addonSlider(30);
  Row(rows, "goal_strength", "goal strength", SettingType::kNumber, simulate)
      .flag("--goal-strength", "S")
      .field<&O::goalStrength>()
      .range(0, 1, "", "a free simulation")
      .help("how strongly the simulation is pulled towards the bake (the cloth's pin goal)")
      .addon("simulate")
      .addonProperty("simulate_goal_strength")
      .addonSlider(kNoLimit, 2, 1);
  Row(rows, "seam", "seam", SettingType::kInt, simulate)
      .flag("--seam", "N")
      .field<&O::seam>()
      .range(0, 1000, "frames", "a hard cut")
      .help(
          "frames before a window's first handed-back frame that cross-fade from the bake to "
          "the simulation (within the warm-up)")
      .addon("simulate")
      .addonProperty("simulate_seam")
      .addonSlider(20);
  Row(rows, "carry", "carry", SettingType::kInt, simulate)
      .flag("--carry", "N")
      .field<&O::carry>()
      .range(0, 10000, "frames", "a hard cut")
      .help(
          "frames after a window over which its last frame's residual (simulated - baked) is "
          "carried onto the bake, fading to 0 (the cloth's state persists)")
      .addon("simulate")
      .addonProperty("simulate_carry")
      .addonSlider(30);
  Row(rows, "from_start", "simulate from the start", SettingType::kBool, simulate)
      .flag("--from-start")
      .field<&O::fromStart>()
      .help(
          "one window from the shot's first frame to its last flagged frame, for cloth whose "
          "warm-started windows do not settle within a warm-up")
      .addon("simulate", "From Start")
      .addonProperty("simulate_from_start");
}

std::vector<SettingRow> makeRows() {
  std::vector<SettingRow> rows;
  weightAndAlignmentRows(rows);
  correctionRows(rows);
  batchAndLayerRows(rows);
  runRows(rows);
  mixRows(rows);
  windRows(rows);
  buildRows(rows);
  poseModelRows(rows);
  simulateRows(rows);
  return rows;
}

// ---- Text -----------------------------------------------------------------------------------

/// "exit fade (exit_fade, --exit-fade)"
std::string settingNames(const Setting& setting) {
  std::string text = std::string(setting.label) + " (" + setting.key;
  if (setting.flag != nullptr) {
    text += std::string(", ") + setting.flag;
  }
  return text + ")";
}

/// A bound of a range: a whole number in full ("100000", not "1e+05").
std::string boundText(double value) {
  if (value == std::floor(value) && std::abs(value) < 1e15) {
    return std::to_string(static_cast<long long>(value));
  }
  return formatSettingValue(value);
}

std::string rangeText(const Setting& setting) {
  std::ostringstream text;
  const char* what = setting.type == SettingType::kInt ? "a whole number" : "a number";
  if (std::isinf(setting.maximum)) {
    text << what << " >= " << boundText(setting.minimum);
  } else {
    text << what << " in [" << boundText(setting.minimum) << ", " << boundText(setting.maximum)
         << "]";
  }
  if (*setting.unit != '\0') {
    text << " " << setting.unit;
  }
  return text.str();
}

/// What a number setting takes: "auto or a whole number in [0, 120] frames" (or `takes`).
std::string takesText(const Setting& setting) {
  if (setting.takes != nullptr) {
    return setting.takes;
  }
  std::string words;
  for (std::size_t i = 0; i < setting.words.size(); ++i) {
    words += setting.words[i].first + (i + 1 < setting.words.size() ? ", " : " or ");
  }
  return words + rangeText(setting);
}

/// Refuses a number outside the range of `setting` (a word's value passes when `words`) or one
/// its `accepts` refuses, showing it as `shown`.
void checkNumber(const Setting& setting, double number, const std::string& shown, bool words) {
  for (const auto& word : setting.words) {
    if (words && number == word.second) {
      return;
    }
  }
  const bool inRange =
      std::isfinite(number) && number >= setting.minimum && number <= setting.maximum;
  if (inRange && setting.accepts != nullptr) {
    const SettingValue value = setting.type == SettingType::kInt
                                   ? SettingValue(static_cast<int>(number))
                                   : SettingValue(number);
    if (setting.accepts(value)) {
      return;
    }
  } else if (inRange) {
    return;
  }
  const std::string zero =
      *setting.zero != '\0' ? std::string("0 = ") + setting.zero + "; " : std::string();
  if (inRange || setting.takes != nullptr) {
    DS_THROW(kUsage, "the ", settingNames(setting), " must be ", takesText(setting), " (", zero,
             "got ", shown, ")");
  }
  // Out of range: the bound the value breaks, then all it takes when that is more than one bound.
  const char* what = setting.type == SettingType::kInt ? "a whole number" : "a number";
  const std::string broken = !std::isfinite(number) ? std::string("a finite number")
                             : number < setting.minimum
                                 ? what + std::string(" >= ") + formatSettingValue(setting.minimum)
                                 : what + std::string(" <= ") + formatSettingValue(setting.maximum);
  const std::string unit =
      std::isfinite(number) && *setting.unit != '\0' ? std::string(" ") + setting.unit : "";
  const std::string allowed = std::isinf(setting.maximum) && setting.words.empty()
                                  ? std::string()
                                  : "; allowed: " + takesText(setting);
  DS_THROW(kUsage, "the ", settingNames(setting), " must be ", broken, unit, " (", zero, "got ",
           shown, allowed, ")");
}

const char* scopeName(SettingScope scope) {
  switch (scope) {
    case SettingScope::kEvaluator:
      return "evaluator";
    case SettingScope::kBake:
      return "bake";
    case SettingScope::kLayer:
      return "layer";
    case SettingScope::kBuild:
      return "build";
    case SettingScope::kSimulate:
      return "simulate";
  }
  return "?";
}

const char* typeName(SettingType type) {
  switch (type) {
    case SettingType::kBool:
      return "bool";
    case SettingType::kInt:
      return "int";
    case SettingType::kNumber:
      return "number";
    case SettingType::kText:
      return "text";
    case SettingType::kChoice:
      return "choice";
    case SettingType::kObject:
      return "object";
  }
  return "?";
}

/// The value as JSON (numbers as numbers).
nlohmann::json valueJson(const SettingValue& value) {
  return std::visit([](const auto& v) { return nlohmann::json(v); }, value);
}

/// The value a setting has where the message's reader set it (the bake's file path, else the
/// evaluator's value).
SettingValue viewValue(const Setting& setting, const SettingsView& view) {
  if (view.bake != nullptr && hasBakeValue(setting)) {
    return settingValue(setting, *view.bake);
  }
  return setting.getEvaluator(view.evaluator);
}

std::string unusedMessage(const Setting& setting, const SettingValue& value,
                          const SettingsView& view) {
  const EvaluatorSettings& s = view.evaluator;
  const std::string text = formatSettingValue(value);
  std::ostringstream out;
  out << setting.label;
  if (setting.type != SettingType::kBool) {
    out << " '" << text << "'";
  }
  out << " (" << setting.key << "=" << text;
  if (setting.flag != nullptr) {
    out << ", " << setting.flag << (setting.valueName != nullptr ? " " + text : "");
  }
  out << ") has no effect here: it applies " << setting.usedWhen << "; here weights "
      << weightModeName(s.weightMode) << ", align " << alignModeName(s.align) << ", blend "
      << blendModeName(s.blend) << ", correction " << (s.correct ? "on" : "off") << ", resolution "
      << (s.resolve ? "on" : "off");
  if (setting.scope == SettingScope::kBake && view.bake != nullptr) {
    out << ", maximum weight change " << s.maxWeightChange << ", compression "
        << exrCompressionName(view.bake->compression);
  }
  out << (setting.whenUnused == WhenUnused::kRefuse ? ". Drop it, or change those settings"
                                                    : "; it is ignored");
  return out.str();
}

}  // namespace settings_impl

using settings_impl::settingNames;

// ---- The public functions ---------------------------------------------------------------------

namespace pipeline {

const std::vector<SettingRow>& settingRows() {
  static const std::vector<SettingRow> rows = settings_impl::makeRows();
  return rows;
}

std::uint64_t hashSettings(const Model& model, const OutputHashFields* output,
                           const char* version) {
  const HashInput input{model, output};
  Hasher hasher;
  hasher.addValue(model.db.contentHash());
  for (const SettingRow& row : settingRows()) {
    if (row.hash != nullptr) {
      row.hash(input, hasher);
    }
  }
  hasher.addString(version);
  std::uint64_t value = hasher.value();
  for (const SettingRow& row : settingRows()) {
    if (row.hashAfterVersion != nullptr) {
      value = row.hashAfterVersion(input, value);
    }
  }
  return value;
}

void describeSettings(const Model& model, nlohmann::json& settings) {
  for (const SettingRow& row : settingRows()) {
    if (row.describe != nullptr) {
      row.describe(model, settings);
    } else if (row.setting.reportKey != nullptr && row.setting.getEvaluator != nullptr) {
      settings[row.setting.reportKey] =
          settings_impl::valueJson(row.setting.getEvaluator(model.settings));
    }
  }
}

}  // namespace pipeline

const std::vector<Setting>& settingsTable() {
  static const std::vector<Setting> table = [] {
    std::vector<Setting> settings;
    for (const pipeline::SettingRow& row : pipeline::settingRows()) {
      settings.push_back(row.setting);
    }
    return settings;
  }();
  return table;
}

const Setting* findSettingByKey(const std::string& key) {
  for (const Setting& setting : settingsTable()) {
    if (key == setting.key) {
      return &setting;
    }
  }
  return nullptr;
}

const Setting& findSetting(const std::string& key) {
  const Setting* setting = findSettingByKey(key);
  if (setting == nullptr) {
    DS_THROW(kUsage, "there is no setting '", key,
             "'; the settings are listed in "
             "docs/commands.md (Settings)");
  }
  return *setting;
}

bool hasEvaluatorValue(const Setting& setting) {
  return setting.setEvaluator != nullptr;
}

bool hasBakeValue(const Setting& setting) {
  return setting.getBake != nullptr || setting.getLayer != nullptr ||
         (setting.scope == SettingScope::kEvaluator && setting.setEvaluator != nullptr);
}

bool hasLayerValue(const Setting& setting) {
  return setting.getLayer != nullptr;
}

bool hasBuildValue(const Setting& setting) {
  return setting.getBuild != nullptr;
}

bool hasSimulateValue(const Setting& setting) {
  return setting.getSimulate != nullptr;
}

std::vector<const Setting*> settingsOfScope(SettingScope scope) {
  std::vector<const Setting*> settings;
  for (const Setting& setting : settingsTable()) {
    if (setting.scope == scope) {
      settings.push_back(&setting);
    }
  }
  return settings;
}

SettingValue settingValue(const Setting& setting, const EvaluatorSettings& settings) {
  if (!hasEvaluatorValue(setting)) {
    DS_THROW(kUsage, "the ", settingNames(setting), " has no value in EvaluatorSettings");
  }
  return setting.getEvaluator(settings);
}

SettingValue settingValue(const Setting& setting, const BakeOptions& options) {
  if (setting.getBake != nullptr) {
    return setting.getBake(options);
  }
  if (setting.getLayer != nullptr) {
    return setting.getLayer(options.layers);
  }
  return settingValue(setting, options.evaluator);
}

SettingValue settingValue(const Setting& setting, const LayerOptions& options) {
  if (!hasLayerValue(setting)) {
    DS_THROW(kUsage, "the ", settingNames(setting), " has no value in LayerOptions");
  }
  return setting.getLayer(options);
}

SettingValue settingValue(const Setting& setting, const DatabaseBuildOptions& options) {
  if (!hasBuildValue(setting)) {
    DS_THROW(kUsage, "the ", settingNames(setting), " has no value in DatabaseBuildOptions");
  }
  return setting.getBuild(options);
}

SettingValue settingValue(const Setting& setting, const SimulationOptions& options) {
  if (!hasSimulateValue(setting)) {
    DS_THROW(kUsage, "the ", settingNames(setting), " has no value in SimulationOptions");
  }
  return setting.getSimulate(options);
}

SettingValue defaultSettingValue(const Setting& setting) {
  static const BakeOptions defaults;
  static const DatabaseBuildOptions buildDefaults;
  static const SimulationOptions simulateDefaults;
  if (hasBuildValue(setting)) {
    return setting.getBuild(buildDefaults);
  }
  if (hasSimulateValue(setting)) {
    return setting.getSimulate(simulateDefaults);
  }
  if (!hasBakeValue(setting)) {
    return std::string();  // an object no tool has loaded
  }
  return settingValue(setting, defaults);
}

namespace settings_impl {

/// `value` as `setting`'s type (an int taken for a number), checked.
SettingValue checkedValue(const Setting& setting, SettingValue value) {
  if (setting.type == SettingType::kNumber && std::holds_alternative<int>(value)) {
    value = static_cast<double>(std::get<int>(value));
  }
  checkSettingValue(setting, value);
  return value;
}

}  // namespace settings_impl

using settings_impl::checkedValue;

void setSetting(const Setting& setting, EvaluatorSettings& settings, const SettingValue& value) {
  if (!hasEvaluatorValue(setting)) {
    DS_THROW(kUsage, "the ", settingNames(setting),
             " cannot be set from a value in "
             "EvaluatorSettings");
  }
  setting.setEvaluator(settings, checkedValue(setting, value));
}

void setSetting(const Setting& setting, BakeOptions& options, const SettingValue& value) {
  if (setting.setBake != nullptr) {
    setting.setBake(options, checkedValue(setting, value));
  } else if (setting.setLayer != nullptr) {
    setting.setLayer(options.layers, checkedValue(setting, value));
  } else {
    setSetting(setting, options.evaluator, value);
  }
}

void setSetting(const Setting& setting, LayerOptions& options, const SettingValue& value) {
  if (setting.setLayer == nullptr) {
    DS_THROW(kUsage, "the ", settingNames(setting), " cannot be set in LayerOptions");
  }
  setting.setLayer(options, checkedValue(setting, value));
}

void setSetting(const Setting& setting, DatabaseBuildOptions& options, const SettingValue& value) {
  if (setting.setBuild == nullptr) {
    DS_THROW(kUsage, "the ", settingNames(setting), " cannot be set in DatabaseBuildOptions");
  }
  setting.setBuild(options, checkedValue(setting, value));
}

void setSetting(const Setting& setting, SimulationOptions& options, const SettingValue& value) {
  if (setting.setSimulate == nullptr) {
    DS_THROW(kUsage, "the ", settingNames(setting), " cannot be set in SimulationOptions");
  }
  setting.setSimulate(options, checkedValue(setting, value));
}

void checkSettingValue(const Setting& setting, const SettingValue& value) {
  static constexpr std::size_t kIndex[] = {0, 1, 2, 3, 3, 3};  // variant index of each type
  const std::string names = settingNames(setting);
  if (value.index() != kIndex[static_cast<int>(setting.type)]) {
    DS_THROW(kUsage, "the ", names, " takes a ", settings_impl::typeName(setting.type), " (got ",
             formatSettingValue(value), ")");
  }
  if (setting.type == SettingType::kChoice) {
    std::string spellings;
    for (const std::string& choice : setting.choices) {
      if (settings_impl::sameChoice(std::get<std::string>(value), choice)) {
        return;
      }
      spellings += (spellings.empty() ? "" : ", ") + choice;
    }
    DS_THROW(kUsage, "the ", names, " takes ", spellings, " (got '", std::get<std::string>(value),
             "')");
  }
  if (setting.type == SettingType::kInt || setting.type == SettingType::kNumber) {
    const double number =
        setting.type == SettingType::kInt ? std::get<int>(value) : std::get<double>(value);
    settings_impl::checkNumber(setting, number, formatSettingValue(value), true);
  }
}

void checkSettings(const EvaluatorSettings& settings) {
  for (const Setting& setting : settingsTable()) {
    if (hasEvaluatorValue(setting)) {
      checkSettingValue(setting, setting.getEvaluator(settings));
    }
  }
}

void checkBakeSettings(const BakeOptions& options) {
  for (const Setting& setting : settingsTable()) {
    if (setting.scope == SettingScope::kBake) {
      checkSettingValue(setting, settingValue(setting, options));
    }
  }
}

void checkSimulationSettings(const SimulationOptions& options) {
  for (const Setting* setting : settingsOfScope(SettingScope::kSimulate)) {
    checkSettingValue(*setting, settingValue(*setting, options));
  }
}

SettingValue parseSettingValue(const Setting& setting, const std::string& text) {
  const std::string names = settingNames(setting);
  for (const auto& [word, value] : setting.words) {
    if (text == word) {
      return setting.type == SettingType::kInt ? SettingValue(static_cast<int>(value))
                                               : SettingValue(value);
    }
  }
  char* end = nullptr;
  switch (setting.type) {
    case SettingType::kBool:
      if (text == "true" || text == "1" || text == "on") {
        return true;
      }
      if (text == "false" || text == "0" || text == "off") {
        return false;
      }
      DS_THROW(kUsage, "the ", names, " takes true or false (got '", text, "')");
    case SettingType::kInt: {
      errno = 0;
      const long value = std::strtol(text.c_str(), &end, 10);
      if (text.empty() || *end != '\0' || errno != 0 || value < -settings_impl::kMaxWhole ||
          value > settings_impl::kMaxWhole) {
        DS_THROW(kUsage, "the ", names, " takes a whole number (got '", text, "')");
      }
      // A number a word stands for is given as the word ("-1" is not "auto").
      settings_impl::checkNumber(setting, static_cast<double>(value), "'" + text + "'", false);
      return static_cast<int>(value);
    }
    case SettingType::kNumber: {
      const double value = std::strtod(text.c_str(), &end);
      if (text.empty() || *end != '\0') {
        DS_THROW(kUsage, "the ", names, " takes a number (got '", text, "')");
      }
      settings_impl::checkNumber(setting, value, "'" + text + "'", false);
      return value;
    }
    default:
      return text;
  }
}

std::string formatSettingValue(const SettingValue& value) {
  if (const bool* flag = std::get_if<bool>(&value)) {
    return *flag ? "true" : "false";
  }
  if (const int* whole = std::get_if<int>(&value)) {
    return std::to_string(*whole);
  }
  if (const double* number = std::get_if<double>(&value)) {
    // The shortest text that reads back to the same double.
    char text[32];
    for (int digits = 1; digits <= 17; ++digits) {
      std::snprintf(text, sizeof(text), "%.*g", digits, *number);
      if (std::strtod(text, nullptr) == *number) {
        break;
      }
    }
    return text;
  }
  return std::get<std::string>(value);
}

std::string formatSettingValue(const Setting& setting, const SettingValue& value) {
  for (const auto& [word, number] : setting.words) {
    if ((std::holds_alternative<int>(value) && std::get<int>(value) == number) ||
        (std::holds_alternative<double>(value) && std::get<double>(value) == number)) {
      return word;
    }
  }
  return formatSettingValue(value);
}

std::vector<UnusedSetting> unusedSettings(const SettingsView& view,
                                          const std::vector<std::string>& given) {
  std::vector<UnusedSetting> unused;
  for (const Setting& setting : settingsTable()) {
    const bool bake = setting.scope == SettingScope::kBake;
    if (setting.used == nullptr || (bake && view.bake == nullptr) ||
        (!bake && setting.getEvaluator == nullptr)) {
      continue;
    }
    const SettingValue value = settings_impl::viewValue(setting, view);
    bool set = value != defaultSettingValue(setting);
    for (const std::string& key : given) {
      set = set || key == setting.key;
    }
    if (set && !setting.used(view)) {
      unused.push_back({&setting, settings_impl::unusedMessage(setting, value, view)});
    }
  }
  return unused;
}

std::vector<std::string> refuseUnusedSettings(const std::vector<UnusedSetting>& unused) {
  std::vector<std::string> warnings;
  for (const UnusedSetting& entry : unused) {
    if (entry.setting->whenUnused == WhenUnused::kRefuse) {
      DS_THROW(kUsage, entry.message);
    }
    warnings.push_back(entry.message);
  }
  return warnings;
}

std::string describeBakeSettings(const BakeOptions& options) {
  nlohmann::json settings = nlohmann::json::object();
  for (const pipeline::SettingRow& row : pipeline::settingRows()) {
    if (row.describeBake != nullptr) {
      row.describeBake(options, settings);
    } else if (row.setting.scope == SettingScope::kBake && row.setting.reportKey != nullptr) {
      settings[row.setting.reportKey] =
          settings_impl::valueJson(settingValue(row.setting, options));
    }
  }
  return jsonText(settings);
}

namespace settings_impl {

nlohmann::json nullable(const char* text) {
  return text != nullptr ? nlohmann::json(text) : nlohmann::json();
}

nlohmann::json finiteOrNull(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json();
}

/// The entries a row writes into the report's settings (ReportEntry), for the schema.
nlohmann::json reportJson(const pipeline::SettingRow& row) {
  nlohmann::json entries = nlohmann::json::array();
  for (const pipeline::ReportEntry& entry : row.report) {
    entries.push_back(
        {{"path", entry.path}, {"schema", nullable(entry.schema)}, {"required", entry.required}});
  }
  return entries;
}

/// How the add-on shows the row (AddonView), or null.
nlohmann::json addonJson(const pipeline::AddonView& view) {
  if (view.panel == nullptr) {
    return nlohmann::json();
  }
  nlohmann::json choices = nlohmann::json::array();
  for (const pipeline::AddonChoice& choice : view.choices) {
    choices.push_back(
        {{"choice", choice.choice}, {"name", choice.name}, {"description", choice.description}});
  }
  return {{"panel", view.panel},
          {"name", nullable(view.name)},
          {"text", nullable(view.text)},
          {"heading", nullable(view.heading)},
          {"property", nullable(view.property)},
          {"active_with", nullable(view.activeWith)},
          {"checkbox", nullable(view.checkbox)},
          {"soft_maximum", finiteOrNull(view.softMaximum)},
          {"precision", view.precision},
          {"step", view.step},
          {"choices", choices},
          {"default", view.defaultValue ? valueJson(*view.defaultValue) : nlohmann::json()},
          {"default_why", view.defaultWhy}};
}

nlohmann::json rowJson(const pipeline::SettingRow& row) {
  const Setting& s = row.setting;
  const bool valued =
      hasBakeValue(s) || hasEvaluatorValue(s) || hasBuildValue(s) || hasSimulateValue(s);
  nlohmann::json words = nlohmann::json::array();
  for (const auto& [word, value] : s.words) {
    words.push_back({{"word", word}, {"value", value}});
  }
  nlohmann::json json{{"key", s.key},
                      {"label", s.label},
                      {"flag", nullable(s.flag)},
                      {"value_name", nullable(s.valueName)},
                      {"scope", scopeName(s.scope)},
                      {"type", typeName(s.type)},
                      {"default", valued ? valueJson(defaultSettingValue(s)) : nlohmann::json()},
                      {"default_text", valued ? formatSettingValue(s, defaultSettingValue(s)) : ""},
                      {"choices", s.choices},
                      {"words", words},
                      {"takes", nullable(s.takes)},
                      {"unit", s.unit},
                      {"zero", s.zero},
                      {"help", s.help},
                      {"hashed", s.hashed},
                      {"report_key", nullable(s.reportKey)},
                      {"report", reportJson(row)},
                      {"report_resolves", nullable(row.reportResolves)},
                      {"used_when", s.usedWhen},
                      {"when_unused", s.used == nullptr                     ? "always used"
                                      : s.whenUnused == WhenUnused::kRefuse ? "refused"
                                                                            : "warned"},
                      {"addon", addonJson(row.addon)}};
  if (s.type == SettingType::kInt || s.type == SettingType::kNumber) {
    json["minimum"] = s.minimum;
    json["maximum"] = finiteOrNull(s.maximum);
  }
  return json;
}

}  // namespace settings_impl

std::string settingsTableJson() {
  nlohmann::json table = nlohmann::json::array();
  for (const pipeline::SettingRow& row : pipeline::settingRows()) {
    table.push_back(settings_impl::rowJson(row));
  }
  return jsonText(table, 1);
}

namespace settings_impl {

/// Text for a Markdown table cell: pipes escaped.
std::string cell(const std::string& text) {
  std::string out;
  for (const char c : text) {
    out += c == '|' ? std::string("\\|") : std::string(1, c);
  }
  return out;
}

std::string markdownRange(const Setting& s) {
  std::string range;
  if (s.type == SettingType::kChoice) {
    for (const std::string& choice : s.choices) {
      range += (range.empty() ? "`" : ", `") + choice + "`";
    }
  } else if (s.takes != nullptr) {
    range = s.takes;
  } else if (s.type == SettingType::kInt || s.type == SettingType::kNumber) {
    for (const auto& word : s.words) {
      range += "`" + word.first + "`, ";
    }
    range += std::isinf(s.maximum) ? ">= " + boundText(s.minimum)
                                   : boundText(s.minimum) + " to " + boundText(s.maximum);
    range += *s.unit != '\0' ? std::string(" ") + s.unit : std::string();
    range += *s.zero != '\0' ? std::string(" (0 = ") + s.zero + ")" : std::string();
  }
  return range;
}

/// "`--exit-fade K`", or "-".
std::string markdownFlag(const Setting& s) {
  if (s.flag == nullptr) {
    return "-";
  }
  return std::string("`") + s.flag +
         (s.valueName != nullptr ? std::string(" ") + s.valueName : "") + "`";
}

/// "`0.15`", or "none".
std::string markdownDefault(const Setting& s) {
  const bool valued =
      hasBakeValue(s) || hasEvaluatorValue(s) || hasBuildValue(s) || hasSimulateValue(s);
  const std::string text = valued ? formatSettingValue(s, defaultSettingValue(s)) : "";
  return text.empty() ? "none" : "`" + text + "`";
}

std::string markdownRow(const Setting& s) {
  std::string used = "always";
  if (s.used != nullptr) {
    used = std::string(s.usedWhen) +
           (s.whenUnused == WhenUnused::kRefuse ? "; else refused" : "; else warned about");
  }
  return "| `" + std::string(s.key) + "` | " + markdownFlag(s) + " | " + markdownDefault(s) +
         " | " + cell(markdownRange(s)) + " | " + (s.hashed ? "yes" : "no") + " | " + cell(used) +
         " | " + cell(s.help) + " |\n";
}

}  // namespace settings_impl

std::string settingsTableMarkdown() {
  std::string table =
      "| setting (Python, add-on) | command line | default | range | hashed | used | what it "
      "does |\n|---|---|---|---|---|---|---|\n";
  for (const Setting& setting : settingsTable()) {
    if (setting.scope == SettingScope::kEvaluator || setting.scope == SettingScope::kBake) {
      table += settings_impl::markdownRow(setting);
    }
  }
  return table;
}

std::string settingsTableMarkdown(SettingScope scope) {
  const char* python = scope == SettingScope::kBuild      ? "build_database"
                       : scope == SettingScope::kSimulate ? "plan_simulation"
                                                          : "load_layers";
  std::string table =
      std::string("| setting (Python: ") + python +
      ") | command line | default | range | what it does |\n|---|---|---|---|---|\n";
  for (const Setting* s : settingsOfScope(scope)) {
    table += "| `" + std::string(s->key) + "` | " + settings_impl::markdownFlag(*s) + " | " +
             settings_impl::markdownDefault(*s) + " | " +
             settings_impl::cell(settings_impl::markdownRange(*s)) + " | " +
             settings_impl::cell(s->help) + " |\n";
  }
  return table;
}

}  // namespace drivenshape
