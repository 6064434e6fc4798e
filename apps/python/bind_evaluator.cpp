// SPDX-License-Identifier: Apache-2.0
// Databases, devices, evaluator settings (binding masks, regions, layers) and the Evaluator.
#include "binding.h"

#include <array>
#include <mutex>
#include <sstream>

#include <drivenshape/binding.h>
#include <drivenshape/coverage_check.h>
#include <drivenshape/database.h>
#include <drivenshape/database_build.h>
#include <drivenshape/device.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/layers.h>
#include <drivenshape/regions.h>
#include <drivenshape/settings_table.h>
#include <drivenshape/simulation.h>

namespace drivenshape::python {

namespace {

using Index = py::ssize_t;

/// A Device and the note openDevice("auto") leaves when it falls back to the host path.
struct DeviceHandle {
  std::unique_ptr<Device> device;
  std::string note;
};

/// An Evaluator with what the binding adds: the seconds of the last call, and a lock so that
/// two Python threads calling one evaluator (the GIL is released while it runs) take turns.
struct EvaluatorHandle {
  EvaluatorHandle(const Database& database, EvaluatorSettings settings, Device& device)
      : evaluator(database, std::move(settings), device) {}
  Evaluator evaluator;
  StageSeconds lastSeconds;
  std::mutex mutex;
};

// ---- Inputs -------------------------------------------------------------------------------

const Mesh& meshArgument(py::handle object, std::optional<Mesh>& storage, const char* what) {
  if (isPathLike(object)) {
    const std::string path = pathString(object);
    py::gil_scoped_release release;
    storage = readObj(path);
    return *storage;
  }
  try {
    return object.cast<const Mesh&>();
  } catch (const py::cast_error&) {
    DS_THROW(kUsage, what, " must be a drivenshape.Mesh or an OBJ path, not ",
             std::string(py::str(object.get_type().attr("__name__"))));
  }
}

/// A PointCache, a path (PC2 or EXR pattern) or an array (F, V, 3) starting at `startFrame`.
std::shared_ptr<PointCacheReader> cacheArgument(py::handle object, int startFrame) {
  if (isPathLike(object)) {
    const std::string spec = pathString(object);
    py::gil_scoped_release release;
    return openPointCache(spec);
  }
  if (py::isinstance<PointCacheReader>(object)) {
    return object.cast<std::shared_ptr<PointCacheReader>>();
  }
  return makeArrayCache(object, startFrame, py::none());
}

std::vector<int> optionalFrames(py::handle object, const std::string& what) {
  return object.is_none() ? std::vector<int>() : frameList(object, what);
}

// ---- Settings given as keywords (load_layers, build_database) -------------------------------

/// A keyword's value as the text a command line gives for the setting: a str as it is, a
/// sequence (wind_direction) comma-joined, a number in Python's shortest form (which reads back
/// to the same double); parseSettingValue reads and checks it.
std::string keywordText(py::handle value) {
  if (py::isinstance<py::str>(value)) {
    return py::str(value);
  }
  if (py::isinstance<py::bool_>(value)) {
    return value.cast<bool>() ? "true" : "false";
  }
  if (py::isinstance<py::sequence>(value)) {
    std::string text;
    for (py::handle item : value) {
      text += (text.empty() ? "" : ",") + std::string(py::str(item));
    }
    return text;
  }
  return py::str(value);
}

/// Sets the settings given as `keywords` in `options`: each a setting of the table that `takes`
/// (None leaves it at its default). Error(kUsage) for an unknown keyword, naming the known ones.
template <typename Options>
void setKeywordSettings(const py::kwargs& keywords, bool (*takes)(const Setting&), Options& options,
                        const char* what) {
  for (const auto& [name, value] : keywords) {
    const std::string key = py::str(name);
    const Setting* setting = findSettingByKey(key);
    if (setting == nullptr || !takes(*setting)) {
      std::string known;
      for (const Setting& row : settingsTable()) {
        known += takes(row) ? (known.empty() ? "" : ", ") + std::string(row.key) : "";
      }
      DS_THROW(kUsage, "no ", what, " setting '", key, "' (the settings: ", known, ")");
    }
    if (!value.is_none()) {
      setSetting(*setting, options, parseSettingValue(*setting, keywordText(value)));
    }
  }
}

/// The keywords' part of a docstring: "\n  key (--flag, default X): help" per setting.
std::string keywordsDoc(bool (*takes)(const Setting&)) {
  std::string text;
  for (const Setting& setting : settingsTable()) {
    if (takes(setting)) {
      const std::string value = formatSettingValue(setting, defaultSettingValue(setting));
      text += std::string("\n  ") + setting.key + " (" + setting.flag + ", default " +
              (value.empty() ? "none" : value) + "): " + setting.help;
      text += *setting.unit != '\0' ? std::string(" (") + setting.unit + ")" : "";
      text += *setting.zero != '\0' ? std::string(" (0 = ") + setting.zero + ")" : "";
    }
  }
  return text;
}

bool isLayerSetting(const Setting& setting) {
  return hasLayerValue(setting);
}

bool isBuildSetting(const Setting& setting) {
  return setting.scope == SettingScope::kBuild;
}

bool isSimulateSetting(const Setting& setting) {
  return setting.scope == SettingScope::kSimulate;
}

/// A JSON object (describe_settings, describe_layers) or array (settings_table) as Python.
template <typename Result>
Result parseJson(const std::string& text) {
  return Result(py::module_::import("json").attr("loads")(text));
}

// ---- Records ----------------------------------------------------------------------------

types::JsonDict recordDict(const FrameRecord& record) {
  py::dict out;
  out["frame"] = record.frame;
  out["weights"] = record.weights;
  out["at_zero"] = record.atZero;
  out["at_one"] = record.atOne;
  out["relative_residual"] = record.relativeResidual;
  out["relative_residual_direct"] = record.directResidual;
  out["kkt_residual"] = record.kktResidual;
  out["iterations"] = record.iterations;
  out["align_rotation"] = record.alignRotation;
  out["align_translation"] = record.alignTranslation;
  out["inside_before"] = record.insideBefore;
  out["inside_corrected"] = record.insideCorrected;
  out["inside_after"] = record.insideAfter;
  out["resolved"] = record.resolved;
  out["binding_switches"] = record.bindingSwitches;
  out["max_jump"] = record.maxJump;
  out["max_jump_vertex"] = record.maxJumpVertex;
  out["pose_distance"] = record.poseDistance;
  out["predicted_error"] = record.predictedError;
  out["error_bound"] = record.errorBound;
  out["flagged"] = record.flagged;
  return types::JsonDict(out);
}

types::Records recordList(std::vector<FrameRecord>&& records) {
  py::list out(records.size());
  for (std::size_t i = 0; i < records.size(); ++i) {
    out[i] = py::cast(std::move(records[i]));
  }
  return types::Records(out);
}

// ---- Evaluation ---------------------------------------------------------------------------

struct DriverInput {
  std::vector<int> frames;
  std::optional<FloatArray> array;
};

DriverInput driverInput(const EvaluatorHandle& handle, py::handle frames, py::handle driver,
                        int warmup) {
  DriverInput input;
  input.frames = frameList(frames);
  input.array.emplace(driver, "driver");
  const FrameBlockShape shape = frameBlockShape(*input.array, "driver");
  const int expected = handle.evaluator.driverVertexCount();
  if (shape.vertices != expected) {
    DS_THROW(kInput, "driver: ", shape.vertices,
             " vertices per frame, but the database's driver mesh has ", expected,
             "; pass the positions of the driver the database was built from");
  }
  if (shape.frames != static_cast<int>(input.frames.size())) {
    DS_THROW(kUsage, "driver holds ", shape.frames, " frames but ", input.frames.size(),
             " frame numbers were given");
  }
  if (warmup < 0 || (warmup > 0 && warmup >= shape.frames)) {
    DS_THROW(kUsage, "warmup ", warmup, " must be at least 0 and below the frame count ",
             shape.frames);
  }
  return input;
}

std::vector<FrameRecord> runEvaluator(EvaluatorHandle& handle, const DriverInput& input,
                                      float* cloth, int warmup) {
  const int count = static_cast<int>(input.frames.size());
  std::vector<FrameRecord> records(static_cast<std::size_t>(count - warmup));
  if (count == 0) {
    handle.lastSeconds.clear();
    return records;
  }
  StageSeconds seconds;
  {
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(handle.mutex);
    seconds = handle.evaluator.evaluate(count, input.frames.data(), input.array->data(), cloth,
                                        records.data(), warmup);
    handle.lastSeconds = seconds;
  }
  return records;
}

types::Evaluation evaluate(EvaluatorHandle& handle, types::Frames frames, types::ArrayLike driver,
                           int warmup) {
  const DriverInput input = driverInput(handle, frames, driver, warmup);
  const Index count = static_cast<Index>(input.frames.size()) - warmup;
  const Index drivenCount = handle.evaluator.drivenVertexCount();
  // Not zero-filled: the evaluator writes every value.
  std::shared_ptr<float[]> cloth(new float[static_cast<std::size_t>(count * drivenCount * 3)]);
  std::vector<FrameRecord> records = runEvaluator(handle, input, cloth.get(), warmup);
  return types::Evaluation(py::make_tuple(
      ownedFloatArray(std::move(cloth), {count, drivenCount, 3}), recordList(std::move(records))));
}

types::Records evaluateInto(EvaluatorHandle& handle, types::Frames frames, types::ArrayLike driver,
                            types::Float32Array out, int warmup) {
  const DriverInput input = driverInput(handle, frames, driver, warmup);
  const FloatArray target(out, "out", true);
  const Index count = static_cast<Index>(input.frames.size()) - warmup;
  const Index drivenCount = handle.evaluator.drivenVertexCount();
  const bool oneFrame = target.ndim() == 2 && count == 1;
  const bool fits = (target.ndim() == 3 && target.dim(0) == count && target.dim(1) == drivenCount &&
                     target.dim(2) == 3) ||
                    (oneFrame && target.dim(0) == drivenCount && target.dim(1) == 3);
  if (!fits) {
    DS_THROW(kUsage, "out must be shaped (", count, ", ", drivenCount, ", 3) float32 (frames ",
             "after warm-up, driven vertices, xyz); got ", target.describe());
  }
  return recordList(runEvaluator(handle, input, target.mutableData(), warmup));
}

/// A float32 copy of per-vertex weights.
types::Float32Array weightArray(std::vector<float> weights) {
  const Index size = static_cast<Index>(weights.size());
  return types::Float32Array(ownedArray(std::move(weights), {size}));
}

void bindSettingObjects(py::module_& module) {
  py::class_<BindingMask>(module, "BindingMask",
                          "Which driver triangles each driven vertex may bind to "
                          "(load_binding_mask / parse_binding_mask).")
      .def(py::init<std::vector<int>, std::vector<std::vector<int>>>(), py::arg("vertex_class"),
           py::arg("class_triangles"),
           "vertex_class: one class id per driven vertex (-1 = any triangle); class_triangles: "
           "the driver triangle ids of each class")
      .def_static("all", &BindingMask::all, py::arg("driven_vertex_count"))
      .def_property_readonly("driven_vertex_count", &BindingMask::drivenVertexCount)
      .def_property_readonly("class_count", &BindingMask::classCount)
      .def_property_readonly("vertex_classes", &BindingMask::vertexClasses)
      .def(
          "class_triangles",
          [](const BindingMask& mask, int index) {
            if (index < 0 || index >= mask.classCount()) {
              DS_THROW(kUsage, "binding-mask class ", index, " does not exist; the mask has ",
                       mask.classCount(), " classes");
            }
            return mask.classTriangles(index);
          },
          py::arg("class_index"), "the sorted driver triangle ids of one class")
      .def_property_readonly("is_all", &BindingMask::isAll);

  py::class_<RegionSet>(module, "RegionSet",
                        "Regions with their own weights (load_regions / parse_regions).")
      .def_property_readonly("count", &RegionSet::count)
      .def_property_readonly("names",
                             [](const RegionSet& set) {
                               std::vector<std::string> names;
                               for (const Region& region : set.regions) {
                                 names.push_back(region.name);
                               }
                               return names;
                             })
      .def_readonly("falloff", &RegionSet::falloff);

  py::class_<LayerSettings>(module, "LayerSettings",
                            "Layers after the correction: a mix with another cache, wind "
                            "(load_layers). The default is no layer.")
      .def(py::init<>())
      .def_property_readonly("has_mix", &LayerSettings::hasMix)
      .def_property_readonly("has_wind", &LayerSettings::hasWind)
      .def_property_readonly("empty", &LayerSettings::empty)
      .def_property_readonly("mix_cache",
                             [](const LayerSettings& layers) { return layers.options.mixCache; })
      .def_property_readonly(
          "mix_weights", [](const LayerSettings& layers) { return weightArray(layers.mixWeights); })
      .def_property_readonly("wind_weights", [](const LayerSettings& layers) {
        return weightArray(layers.windWeights);
      });
}

// ---- EvaluatorSettings, from the settings table ----------------------------------------------
// Every evaluator setting of drivenshape/settings_table.h is a keyword, an attribute and a part
// of the repr, spelled by its key. Values go through the table (setSetting checks them); the
// three kObject settings are the objects above.

/// The Python value of `setting` in `s`: a bool, int, float or str, or the loaded object.
py::object settingObject(const Setting& setting, const EvaluatorSettings& s) {
  const std::string key = setting.key;
  if (key == "binding_mask") {
    return s.bindingMask ? py::cast(*s.bindingMask) : py::none();
  }
  if (key == "regions") {
    return s.regions ? py::cast(*s.regions) : py::none();
  }
  if (key == "layers") {
    return py::cast(s.layers);
  }
  return std::visit([](const auto& value) { return py::cast(value); }, settingValue(setting, s));
}

/// Sets `setting` of `s` from a Python value (None clears an object setting).
void setSettingObject(const Setting& setting, EvaluatorSettings& s, py::handle value) {
  const std::string key = setting.key;
  try {
    if (key == "binding_mask") {
      s.bindingMask = value.is_none() ? std::nullopt : std::optional(value.cast<BindingMask>());
    } else if (key == "regions") {
      s.regions = value.is_none() ? std::nullopt : std::optional(value.cast<RegionSet>());
    } else if (key == "layers") {
      s.layers = value.is_none() ? LayerSettings() : value.cast<LayerSettings>();
    } else if (setting.type == SettingType::kBool) {
      setSetting(setting, s, value.cast<bool>());
    } else if (setting.type == SettingType::kInt) {
      setSetting(setting, s, value.cast<int>());
    } else if (setting.type == SettingType::kNumber) {
      setSetting(setting, s, value.cast<double>());
    } else {
      setSetting(setting, s, value.cast<std::string>());
    }
  } catch (const py::cast_error&) {
    static const char* const kTypes[] = {"a bool", "an int", "a float", "a str", "a str", ""};
    const std::string what = setting.type == SettingType::kObject
                                 ? std::string("a ") + setting.label + " object or None"
                                 : kTypes[static_cast<int>(setting.type)];
    throw py::type_error("EvaluatorSettings." + key + " takes " + what + ", not " +
                         std::string(py::str(value.get_type().attr("__name__"))));
  }
}

/// Every evaluator setting of the table, in table order.
std::vector<const Setting*> evaluatorSettings() {
  std::vector<const Setting*> settings;
  for (const Setting& setting : settingsTable()) {
    if (setting.scope == SettingScope::kEvaluator) {
      settings.push_back(&setting);
    }
  }
  return settings;
}

std::string settingsRepr(const EvaluatorSettings& s) {
  std::string text = "EvaluatorSettings(";
  for (const Setting* setting : evaluatorSettings()) {
    std::string value;
    if (setting->type == SettingType::kObject) {
      const bool set = !std::get<std::string>(setting->getEvaluator(s)).empty();
      value = set ? std::string("<") + setting->label + ">" : "None";
    } else {
      value = py::repr(settingObject(*setting, s));
    }
    text += (text.back() == '(' ? "" : ", ") + std::string(setting->key) + "=" + value;
  }
  return text + ")";
}

/// The class's docstring: its keywords with their defaults and help.
const char* settingsDoc() {
  static const std::string doc = [] {
    const EvaluatorSettings defaults;
    std::string text =
        "Everything that decides the cloth of a frame (the settings table, docs/commands.md); "
        "the defaults are those of `drivenshape bake`. Keyword arguments only; binding_mask, "
        "regions and layers come from load_binding_mask, load_regions and load_layers.\n";
    for (const Setting* setting : evaluatorSettings()) {
      const std::string value = setting->type == SettingType::kObject
                                    ? std::string("None")
                                    : std::string(py::repr(settingObject(*setting, defaults)));
      text += std::string("\n") + setting->key + "=" + value + ": " + setting->help;
    }
    return text;
  }();
  return doc.c_str();
}

/// The Python type of a setting's value, as the stubs write it: from the table's type, a
/// choice as the typing.Literal of its spellings, the objects as their class (None: not set;
/// for layers, which is never None, the setter takes None for no layer).
std::string settingPythonType(const Setting& setting, bool setter) {
  const std::string key = setting.key;
  if (key == "binding_mask") {
    return "BindingMask | None";
  }
  if (key == "regions") {
    return "RegionSet | None";
  }
  if (key == "layers") {
    return setter ? "LayerSettings | None" : "LayerSettings";
  }
  switch (setting.type) {
    case SettingType::kBool:
      return "bool";
    case SettingType::kInt:
      return "int";
    case SettingType::kNumber:
      return "float";
    case SettingType::kChoice: {
      std::string text = "typing.Literal[";
      for (const std::string& choice : setting.choices) {
        text += (text.back() == '[' ? "" : ", ") + std::string(py::repr(py::str(choice)));
      }
      return text + "]";
    }
    case SettingType::kText:
    case SettingType::kObject:
      break;
  }
  return "str";
}

/// The constructor's signature, one keyword per evaluator setting with its type and default:
/// pybind11 would show `**kwargs`, which says nothing to help() or a type checker.
std::string settingsInitSignature() {
  const EvaluatorSettings defaults;
  std::string text = "__init__(self, *";
  for (const Setting* setting : evaluatorSettings()) {
    const std::string value = setting->type == SettingType::kObject
                                  ? std::string("None")
                                  : std::string(py::repr(settingObject(*setting, defaults)));
    text +=
        std::string(", ") + setting->key + ": " + settingPythonType(*setting, true) + " = " + value;
  }
  return text + ") -> None";
}

/// Each setting as a property whose getter and setter carry their Python types (their
/// signatures are written here, as the constructor's: the values are Python objects).
void bindSettingProperties(py::class_<EvaluatorSettings>& settings) {
  for (const Setting* setting : evaluatorSettings()) {
    py::cpp_function getter;
    py::cpp_function setter;
    {
      py::options options;
      options.disable_function_signatures();
      const std::string type = settingPythonType(*setting, false);
      getter = py::cpp_function(
          [setting](const EvaluatorSettings& s) { return settingObject(*setting, s); },
          ("(self) -> " + type).c_str());
      setter = py::cpp_function(
          [setting](EvaluatorSettings& s, py::handle value) {
            setSettingObject(*setting, s, value);
          },
          ("(self, value: " + settingPythonType(*setting, true) + ") -> None").c_str());
    }
    settings.def_property(setting->key, getter, setter, setting->help);
  }
}

void bindEvaluatorSettings(py::module_& module) {
  py::class_<EvaluatorSettings> settings(module, "EvaluatorSettings", settingsDoc());
  {
    py::options options;
    options.disable_function_signatures();
    const std::string doc = settingsInitSignature() +
                            "\n\nKeyword arguments only, one per evaluator setting (see the "
                            "class's docstring); the others keep their defaults.";
    settings.def(py::init([](const py::kwargs& keywords) {
                   EvaluatorSettings s;
                   for (const auto& [name, value] : keywords) {
                     const std::string key = py::str(name);
                     const Setting* setting = findSettingByKey(key);
                     if (setting == nullptr || setting->scope != SettingScope::kEvaluator) {
                       throw py::type_error(
                           "EvaluatorSettings() got an unexpected keyword argument '" + key + "'");
                     }
                     setSettingObject(*setting, s, value);
                   }
                   return s;
                 }),
                 doc.c_str());
  }
  bindSettingProperties(settings);
  settings.def("__repr__", &settingsRepr);
  module.def(
      "settings_table", []() { return parseJson<types::JsonList>(settingsTableJson()); },
      "The settings table (drivenshape/settings_table.h) as a list of dicts: key, flag, type, "
      "default, minimum, maximum, choices, unit, help, hashed, used_when, ...");
}

void bindSettingLoaders(py::module_& module) {
  // The loaders the command line uses (bake's --bind, --regions, --mix..., --wind...).
  module.def(
      "load_binding_mask",
      [](types::Path path, const Database& db) {
        return readBindingMask(pathString(path), db.driverMesh, db.drivenMesh);
      },
      py::arg("path"), py::arg("database"),
      "readBindingMask: the binding-mask JSON file (bake --bind) for the database's meshes");
  module.def(
      "parse_binding_mask",
      [](const std::string& text, const Database& db, const std::string& source) {
        return parseBindingMask(text, source, db.driverMesh, db.drivenMesh);
      },
      py::arg("text"), py::arg("database"), py::arg("source") = "(string)",
      "parseBindingMask: the same from JSON text");
  module.def(
      "load_regions",
      [](types::Path path, const Database& db) {
        return readRegions(pathString(path), db.driverMesh, db.drivenMesh);
      },
      py::arg("path"), py::arg("database"), "readRegions: a region JSON file (bake --regions)");
  module.def(
      "parse_regions",
      [](const std::string& text, const Database& db, const std::string& source) {
        return parseRegions(text, source, db.driverMesh, db.drivenMesh);
      },
      py::arg("text"), py::arg("database"), py::arg("source") = "(string)",
      "parseRegions: the same from JSON text");
  // The keywords are the settings table's layer settings (and frames_per_second), as
  // build_database's are db build's: the bake's --mix, --wind-* and --fps without the dashes.
  static const std::string layersDoc =
      "loadLayers: the layers of the bake's --mix, --mix-weight, --mix-falloff, --wind-* and "
      "--fps, given as keywords named as the settings table names them (a value is read as the "
      "command line reads its text; None keeps the default; an unknown keyword or a value it "
      "refuses is an Error); weight maps are .json, .exr or group:NAME specs (see "
      "docs/commands.md):" +
      keywordsDoc(&isLayerSetting);
  module.def(
      "load_layers",
      [](const Database& db, const py::kwargs& settings) {
        LayerOptions options;
        setKeywordSettings(settings, &isLayerSetting, options, "layer");
        py::gil_scoped_release release;
        return loadLayers(options, db.drivenMesh);
      },
      py::arg("database"), layersDoc.c_str());
}

void bindSettings(py::module_& module) {
  bindSettingObjects(module);
  bindEvaluatorSettings(module);
  bindSettingLoaders(module);
}

void bindDatabaseClass(py::module_& module) {
  py::class_<Database>(module, "Database",
                       "N pairs of driver and driven shapes with their meshes "
                       "(load_database / build_database).")
      .def_property_readonly("shape_count", &Database::shapeCount)
      .def_readonly("frames", &Database::frames, "source frame of each shape, in pick order")
      .def_property_readonly("reasons",
                             [](const Database& db) {
                               std::vector<std::string> names;
                               for (PickReason reason : db.reasons) {
                                 names.push_back(pickReasonName(reason));
                               }
                               return names;
                             })
      .def_readonly("pick_distances", &Database::pickDistances)
      .def_readonly("driver_mesh", &Database::driverMesh)
      .def_readonly("driven_mesh", &Database::drivenMesh)
      .def_property_readonly("driver_vertex_count", &Database::driverVertexCount)
      .def_property_readonly("driven_vertex_count", &Database::drivenVertexCount)
      .def_property_readonly("content_hash", &Database::contentHash,
                             "hash of the shapes and topologies (identifies the database)")
      .def_property_readonly(
          "driver_shapes",
          [](py::object self) {
            const Database& db = self.cast<const Database&>();
            return types::Float32Array(viewArray(
                db.driverShapes.data(), {db.shapeCount(), db.driverVertexCount(), 3}, self));
          },
          "(N, Vp, 3) float32, read-only view")
      .def_property_readonly(
          "driven_shapes",
          [](py::object self) {
            const Database& db = self.cast<const Database&>();
            return types::Float32Array(viewArray(
                db.drivenShapes.data(), {db.shapeCount(), db.drivenVertexCount(), 3}, self));
          },
          "(N, Vd, 3) float32, read-only view")
      .def_readonly("driver_source", &Database::driverSource)
      .def_readonly("driven_source", &Database::drivenSource)
      .def_readonly("tool_version", &Database::toolVersion)
      .def_readonly("created", &Database::created)
      .def(
          "save",
          [](const Database& db, types::Path path) {
            const std::string file = pathString(path);
            py::gil_scoped_release release;
            saveDatabase(file, db);
          },
          py::arg("path"), "Writes the database file atomically.")
      .def("__repr__", [](const Database& db) {
        return "<drivenshape.Database " + std::to_string(db.shapeCount()) + " shapes, driver " +
               std::to_string(db.driverVertexCount()) + " vertices, driven " +
               std::to_string(db.drivenVertexCount()) + " vertices>";
      });
}

/// `build_database`: the inputs of `drivenshape db build`, and its settings as keywords named
/// by the settings table (its SettingScope::kBuild rows), each value read as its text.
Database buildDatabaseFromArguments(types::MeshSource driverMesh, types::MeshSource drivenMesh,
                                    types::CacheSource driverCache, types::CacheSource drivenCache,
                                    types::OptionalFrames frames, types::OptionalFrames addFrames,
                                    types::OptionalFrames removeFrames,
                                    types::Frame startFrameObject, types::ReferenceClips also,
                                    types::TextOutput log, const py::kwargs& settings) {
  const int startFrame = frameNumber(startFrameObject, "start_frame");
  std::optional<Mesh> driverStorage;
  std::optional<Mesh> drivenStorage;
  const Mesh& driver = meshArgument(driverMesh, driverStorage, "driver_mesh");
  const Mesh& driven = meshArgument(drivenMesh, drivenStorage, "driven_mesh");
  const std::shared_ptr<PointCacheReader> driverFrames = cacheArgument(driverCache, startFrame);
  const std::shared_ptr<PointCacheReader> drivenFrames = cacheArgument(drivenCache, startFrame);
  DatabaseBuildOptions options;
  options.frames = optionalFrames(frames, "frames");
  options.addFrames = optionalFrames(addFrames, "add_frames");
  options.removeFrames = optionalFrames(removeFrames, "remove_frames");
  setKeywordSettings(settings, &isBuildSetting, options, "database build");
  // Extra reference clips (db build --also): (driver_cache, driven_cache[, frames]).
  std::vector<std::shared_ptr<PointCacheReader>> alsoCaches;
  std::vector<ReferenceClip> clips;
  if (!also.is_none()) {
    for (py::handle item : also) {
      const py::sequence clip = py::reinterpret_borrow<py::sequence>(item);
      if (!py::isinstance<py::sequence>(item) || (clip.size() != 2 && clip.size() != 3)) {
        DS_THROW(kUsage, "also: each clip is (driver_cache, driven_cache[, frames])");
      }
      alsoCaches.push_back(cacheArgument(clip[0], startFrame));
      alsoCaches.push_back(cacheArgument(clip[1], startFrame));
      clips.push_back(
          {alsoCaches[alsoCaches.size() - 2].get(), alsoCaches.back().get(),
           clip.size() == 3 ? optionalFrames(clip[2], "also frames") : std::vector<int>()});
    }
  }
  std::ostringstream text;
  std::optional<Database> database;
  {
    py::gil_scoped_release release;
    database = buildDatabase(driver, driven, *driverFrames, *drivenFrames, clips, options,
                             log.is_none() ? nullptr : &text);
  }
  if (!log.is_none()) {
    log.attr("write")(text.str());
  }
  return std::move(*database);
}

}  // namespace

void bindDatabase(py::module_& module) {
  bindDatabaseClass(module);

  module.def(
      "load_database",
      [](types::Path path) {
        const std::string file = pathString(path);
        py::gil_scoped_release release;
        return loadDatabase(file);
      },
      py::arg("path"), "Reads and verifies a database file.");
  module.def(
      "save_database",
      [](types::Path path, const Database& db) {
        const std::string file = pathString(path);
        py::gil_scoped_release release;
        saveDatabase(file, db);
      },
      py::arg("path"), py::arg("database"));
  const std::string settingsHelp = keywordsDoc(&isBuildSetting);
  module.def(
      "build_database", &buildDatabaseFromArguments, py::arg("driver_mesh"), py::arg("driven_mesh"),
      py::arg("driver_cache"), py::arg("driven_cache"), py::kw_only(),
      py::arg("frames") = py::none(), py::arg("add_frames") = py::none(),
      py::arg("remove_frames") = py::none(), py::arg("start_frame") = 1,
      py::arg("also") = py::none(), py::arg("log") = py::none(),
      ("The database of reference caches (drivenshape db build). Meshes are Mesh objects or "
       "OBJ paths; caches are PointCache objects, paths (PC2, EXR pattern) or arrays (F, V, 3) "
       "whose first frame is start_frame. frames: candidates (default every frame of the driver "
       "cache); add_frames are always kept, remove_frames never. also: more reference clips the "
       "pose model is fitted on (db build --also), each (driver_cache, driven_cache) or "
       "(driver_cache, driven_cache, frames). log: a file-like object that receives the pick "
       "log. The settings are keywords, db build's options without their dashes (a value is "
       "read as db build reads its text; an unknown keyword or a value it refuses is an Error):" +
       settingsHelp)
          .c_str());
}

namespace {

void bindDevices(py::module_& module) {
  py::class_<DeviceHandle>(module, "Device",
                           "Where the stages run: the host reference path or one OpenCL "
                           "device (open_device).")
      .def_property_readonly("description",
                             [](const DeviceHandle& d) { return d.device->description(); })
      .def_property_readonly("is_opencl",
                             [](const DeviceHandle& d) { return d.device->isOpenCl(); })
      .def_readonly("note", &DeviceHandle::note,
                    "why open_device('auto') fell back to the host path, else ''")
      .def_property_readonly("programs_built",
                             [](const DeviceHandle& d) { return d.device->programsBuilt(); })
      .def("transfers",
           [](const DeviceHandle& d) {
             const TransferCounts counts = d.device->transfers();
             py::dict out;
             out["uploads"] = counts.uploads;
             out["downloads"] = counts.downloads;
             out["upload_bytes"] = counts.uploadBytes;
             out["download_bytes"] = counts.downloadBytes;
             return types::TransferCounts(out);
           })
      .def("__repr__", [](const DeviceHandle& d) {
        return "<drivenshape.Device " + d.device->description() + ">";
      });

  module.def(
      "open_device",
      [](const std::string& spec) {
        auto handle = std::make_unique<DeviceHandle>();
        py::gil_scoped_release release;
        handle->device = openDevice(spec, &handle->note);
        return handle;
      },
      py::arg("spec") = "auto",
      "'auto' (first GPU, else first OpenCL device, else host: see Device.note), 'host', "
      "'cpu', 'gpu', an index from list_devices() or a substring of a device name; as "
      "--device on the command line.");
  module.def(
      "list_devices",
      []() {
        py::list out;
        for (const OpenClDeviceInfo& info : listOpenClDevices()) {
          py::dict entry;
          entry["index"] = info.index;
          entry["name"] = info.name;
          entry["type"] = info.type;
          entry["platform"] = info.platform;
          entry["version"] = info.version;
          entry["compute_units"] = info.computeUnits;
          entry["global_memory_bytes"] = info.globalMemoryBytes;
          entry["max_allocation_bytes"] = info.maxAllocationBytes;
          entry["description"] = info.description;
          out.append(entry);
        }
        return types::JsonList(out);
      },
      "Every OpenCL device as a dict (index, name, type, platform, version, ...); the host "
      "path is always there too, as open_device('host').");
}

void bindFrameRecord(py::module_& module) {
  py::class_<FrameRecord>(module, "FrameRecord", "What happened to one frame (read-only).")
      .def_readonly("frame", &FrameRecord::frame)
      .def_readonly("weights", &FrameRecord::weights, "k per region, region-major")
      .def_readonly("at_zero", &FrameRecord::atZero, "shapes held at weight 0")
      .def_readonly("at_one", &FrameRecord::atOne)
      .def_readonly("relative_residual", &FrameRecord::relativeResidual)
      .def_readonly("relative_residual_direct", &FrameRecord::directResidual)
      .def_readonly("kkt_residual", &FrameRecord::kktResidual)
      .def_readonly("iterations", &FrameRecord::iterations)
      .def_readonly("align_rotation", &FrameRecord::alignRotation, "R row-major (9) or empty")
      .def_readonly("align_translation", &FrameRecord::alignTranslation)
      .def_readonly("inside_before", &FrameRecord::insideBefore, "-1 where not measured")
      .def_readonly("inside_corrected", &FrameRecord::insideCorrected)
      .def_readonly("inside_after", &FrameRecord::insideAfter)
      .def_readonly("resolved", &FrameRecord::resolved)
      .def_readonly("binding_switches", &FrameRecord::bindingSwitches)
      .def_readonly("max_jump", &FrameRecord::maxJump)
      .def_readonly("max_jump_vertex", &FrameRecord::maxJumpVertex)
      .def_readonly("pose_distance", &FrameRecord::poseDistance,
                    "pose model: how new the pose is (posterior deviation); -1 otherwise")
      .def_readonly("predicted_error", &FrameRecord::predictedError,
                    "pose model: predicted mean vertex error, scene units; -1 otherwise")
      .def_readonly("error_bound", &FrameRecord::errorBound,
                    "pose model: the verdict's bound on the mean vertex error (held at the "
                    "model's verdict level), scene units; -1 otherwise")
      .def_readonly("flagged", &FrameRecord::flagged,
                    "pose model: 1 when the error bound exceeds the coverage tolerance")
      .def("to_dict", &recordDict)
      .def("__repr__", [](const FrameRecord& record) {
        std::ostringstream text;
        text << "<drivenshape.FrameRecord frame " << record.frame << ", residual "
             << record.relativeResidual << ", inside after " << record.insideAfter << ">";
        return text.str();
      });
}

/// The evaluator's warnings about its settings (settings it leaves unused), as Python
/// warnings (UserWarning) too.
std::unique_ptr<EvaluatorHandle> makeEvaluator(const Database& db,
                                               std::optional<EvaluatorSettings> settings,
                                               DeviceHandle& device) {
  EvaluatorSettings chosen = settings.value_or(EvaluatorSettings());
  std::unique_ptr<EvaluatorHandle> handle;
  {
    py::gil_scoped_release release;
    handle = std::make_unique<EvaluatorHandle>(db, std::move(chosen), *device.device);
  }
  for (const std::string& message : handle->evaluator.warnings()) {
    if (PyErr_WarnEx(PyExc_UserWarning, message.c_str(), 1) != 0) {
      throw py::error_already_set();
    }
  }
  return handle;
}

void bindEvaluatorClass(py::module_& module) {
  py::class_<EvaluatorHandle>(
      module, "Evaluator",
      "Frames of driver positions in, cloth positions out (drivenshape/evaluator.h). Keeps "
      "the database and the device alive. Not for two threads at once: calls from several "
      "threads take turns.")
      .def(py::init(&makeEvaluator), py::arg("database"), py::arg("settings"), py::arg("device"),
           py::keep_alive<1, 2>(), py::keep_alive<1, 4>(),
           "Prepares everything that depends only on the database (settings None = the "
           "bake's defaults).")
      .def("evaluate", &evaluate, py::arg("frames"), py::arg("driver"), py::arg("warmup") = 0,
           "(cloth (F - warmup, Vd, 3) float32, [FrameRecord]) of driver positions (F, Vp, 3) "
           "for the frame numbers `frames` (an int for one frame (Vp, 3) or (1, Vp, 3)). The "
           "first `warmup` frames only settle the temporal bound and are dropped. The GIL is "
           "released while it runs; the cloth array owns C++ memory (no copy).")
      .def("evaluate_into", &evaluateInto, py::arg("frames"), py::arg("driver"), py::arg("out"),
           py::arg("warmup") = 0,
           "The same into `out`, a writable C-contiguous float32 array (F - warmup, Vd, 3): "
           "no cloth allocation per call. Returns the records.")
      .def(
          "check_frames",
          [](EvaluatorHandle& h, types::Frames frames) {
            h.evaluator.checkFrames(frameList(frames));
          },
          py::arg("frames"))
      .def("reset_temporal_bound",
           [](EvaluatorHandle& h) {
             // Waits for a call on another thread without holding the GIL it needs to finish.
             py::gil_scoped_release release;
             const std::lock_guard<std::mutex> lock(h.mutex);
             h.evaluator.resetTemporalBound();
           })
      .def("reset_history",
           [](EvaluatorHandle& h) {
             // Waits for a call on another thread without holding the GIL it needs to finish.
             py::gil_scoped_release release;
             const std::lock_guard<std::mutex> lock(h.mutex);
             h.evaluator.resetHistory();
           })
      .def_property_readonly("settings_hash",
                             [](const EvaluatorHandle& h) { return h.evaluator.settingsHash(); })
      .def_property_readonly(
          "history_frames", [](const EvaluatorHandle& h) { return h.evaluator.historyFrames(); },
          "earlier driver frames the pose model reads before each frame: pass them as warm-up "
          "frames for a block (frames played in order one per call are remembered)")
      .def_property_readonly(
          "warnings", [](const EvaluatorHandle& h) { return h.evaluator.warnings(); },
          "settings set away from their defaults that the others leave unused (each was also "
          "a UserWarning when the evaluator was made)")
      .def("describe_settings",
           [](const EvaluatorHandle& h) {
             return parseJson<types::JsonDict>(h.evaluator.describeSettings());
           })
      .def("describe_layers",
           [](const EvaluatorHandle& h) {
             return parseJson<types::JsonDict>(h.evaluator.describeLayers());
           })
      .def_property_readonly("stage_names",
                             [](const EvaluatorHandle& h) { return h.evaluator.stageNames(); })
      .def_property_readonly("settings",
                             [](const EvaluatorHandle& h) { return h.evaluator.settings(); })
      .def_property_readonly(
          "driver_vertex_count",
          [](const EvaluatorHandle& h) { return h.evaluator.driverVertexCount(); })
      .def_property_readonly(
          "driven_vertex_count",
          [](const EvaluatorHandle& h) { return h.evaluator.drivenVertexCount(); })
      .def_property_readonly("device_name",
                             [](const EvaluatorHandle& h) { return h.evaluator.deviceName(); })
      .def_property_readonly("bytes_per_frame",
                             [](const EvaluatorHandle& h) { return h.evaluator.bytesPerFrame(); })
      .def_property_readonly(
          "last_stage_seconds", [](const EvaluatorHandle& h) { return h.lastSeconds; },
          "seconds per stage of the last evaluate call");
}

}  // namespace

void bindEvaluator(py::module_& module) {
  bindDevices(module);
  bindSettings(module);
  bindFrameRecord(module);
  module.def("verdict_holds", &verdictHolds, py::arg("enough"), py::arg("missed"),
             py::arg("enough_true_error"), py::arg("tolerance"), py::arg("level"),
             "Whether a coverage verdict holds against the truth: at `level` > 0 when at least "
             "that share of the `enough` frames it called enough are truly within `tolerance` "
             "(`missed` are not); at level 0 (a report before 0.2.0) when their true mean error "
             "is within it. What `drivenshape eval --report` judges.");
  bindEvaluatorClass(module);
}

namespace {

/// `object` (a dict) as JSON text, through Python's json module.
std::string dictJson(py::handle object, const char* what) {
  if (!py::isinstance<py::dict>(object)) {
    DS_THROW(kUsage, what, " must be a dict, not ",
             std::string(py::str(object.get_type().attr("__name__"))));
  }
  return py::str(py::module_::import("json").attr("dumps")(object));
}

/// plan_simulation's report: a path, or the report's JSON as a dict.
BakeReportCoverage reportArgument(py::handle report) {
  if (isPathLike(report)) {
    const std::string path = pathString(report);
    py::gil_scoped_release release;
    return readBakeReportCoverage(path);
  }
  return parseBakeReportCoverage(dictJson(report, "report"), "(report dict)");
}

/// splice: one window's frames, (F, V, 3) float32, of `vertices` vertices.
std::vector<float> windowArgument(py::handle object, std::size_t w, int vertices) {
  const std::string what = "windows[" + std::to_string(w) + "]";
  const FloatArray array(object, what);
  if (frameBlockShape(array, what).vertices != vertices) {
    DS_THROW(kUsage, what, " is ", array.describe(), "; the baked frames have ", vertices,
             " vertices");
  }
  return std::vector<float>(array.data(), array.data() + array.size());
}

types::JsonDict planSimulationBinding(types::ReportSource report, const py::kwargs& settings) {
  SimulationOptions options;
  setKeywordSettings(settings, &isSimulateSetting, options, "simulation");
  const BakeReportCoverage coverage = reportArgument(report);
  return parseJson<types::JsonDict>(simulationPlanJson(planSimulation(coverage, options)));
}

/// The sources of a splice, by name.
py::list sourceNames(const std::vector<FrameSource>& sources) {
  py::list names;
  for (FrameSource source : sources) {
    names.append(frameSourceName(source));
  }
  return names;
}

types::Spliced spliceBinding(types::JsonDict plan, types::ArrayLike baked,
                             types::ArrayLikes windows) {
  const SimulationPlan parsed = parseSimulationPlan(dictJson(plan, "plan"), "(plan dict)");
  const FloatArray bakedArray(baked, "baked");
  const FrameBlockShape shape = frameBlockShape(bakedArray, "baked");
  const std::vector<float> bakedValues(bakedArray.data(), bakedArray.data() + bakedArray.size());
  std::vector<std::vector<float>> simulated;
  std::size_t w = 0;
  for (py::handle window : windows) {
    simulated.push_back(windowArgument(window, w++, shape.vertices));
  }
  SplicedShot shot;
  {
    py::gil_scoped_release release;
    shot = spliceSimulation(parsed, shape.vertices, bakedValues, simulated);
  }
  const py::list sources = sourceNames(shot.sources);
  const py::ssize_t frames = static_cast<py::ssize_t>(shot.sources.size());
  return types::Spliced(
      py::make_tuple(ownedArray(std::move(shot.positions), {frames, shape.vertices, 3}), sources));
}

types::Sources spliceFilesBinding(types::JsonDict plan, const std::string& bake,
                                  const std::vector<std::string>& windows,
                                  const std::string& output) {
  const SimulationPlan parsed = parseSimulationPlan(dictJson(plan, "plan"), "(plan dict)");
  SplicedShot shot;
  {
    py::gil_scoped_release release;
    shot = spliceSimulationFiles(parsed, bake, windows, output);
  }
  return types::Sources(sourceNames(shot.sources));
}

}  // namespace

void bindSimulation(py::module_& module) {
  static const std::string planDoc =
      "planSimulation (drivenshape simulate's plan): the windows of cloth simulation for the "
      "frames a bake report flags, as the plan JSON (docs/formats.md) as a dict: report, "
      "settings, frames {first, last}, windows [{warmup_from, from, to}], simulated_frames. "
      "report: the bake report's path, or its JSON as a dict. The settings are keywords, "
      "simulate's options without their dashes (a value is read as simulate reads its text; an "
      "unknown keyword or a value it refuses is an Error):" +
      keywordsDoc(&isSimulateSetting);
  module.def("plan_simulation", &planSimulationBinding, py::arg("report"), planDoc.c_str());
  module.def("splice", &spliceBinding, py::arg("plan"), py::arg("baked"), py::arg("windows"),
             "spliceSimulation (drivenshape simulate's splice): the simulated windows spliced "
             "into the baked frames with the plan's seam and carry. plan: plan_simulation's dict "
             "(or a plan file's JSON); baked: (F, V, 3) float32, every frame first..last of the "
             "plan; windows: one (Fw, V, 3) array per window, its frames warmup_from..to. "
             "Returns (positions (F, V, 3) float32, sources: 'baked', 'simulated' or 'blended' "
             "per frame), bitwise what drivenshape simulate writes.");
  module.def("splice_files", &spliceFilesBinding, py::arg("plan"), py::arg("bake"),
             py::arg("windows"), py::arg("output"),
             "spliceSimulationFiles (what drivenshape simulate writes): reads the plan's frames "
             "of the bake's point-cache EXR sequence `bake` and each window's frames "
             "warmup_from..to of the sequences `windows` (one pattern per window), splices them "
             "and writes every frame first..last to the sequence `output`, each file atomically "
             "with the bake's width, compression, topology hash and fps and its source in the "
             "header attribute dsSource. Returns the source of each frame ('baked', "
             "'simulated' or 'blended'). The files are byte for byte those of drivenshape "
             "simulate.");
}

// The shot planner's binding (bind_shot_plan.cpp) plans for an Evaluator's settings.
const Evaluator& evaluatorOf(py::handle object) {
  if (!py::isinstance<EvaluatorHandle>(object)) {
    DS_THROW(kUsage, "evaluator must be a drivenshape.Evaluator, not ",
             std::string(py::str(object.get_type().attr("__name__"))));
  }
  return object.cast<const EvaluatorHandle&>().evaluator;
}

}  // namespace drivenshape::python
