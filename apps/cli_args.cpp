// SPDX-License-Identifier: Apache-2.0
#include "cli_args.h"

#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>

#include <drivenshape/error.h>

#include "atomic_file.h"

namespace drivenshape::cli {

ArgParser::ArgParser(std::string usage, std::string summary)
    : mUsage(std::move(usage)), mSummary(std::move(summary)) {}

ArgParser& ArgParser::option(const std::string& name, const std::string& valueName,
                             const std::string& help, const std::string& defaultValue,
                             bool required) {
  mOrder.push_back(name);
  mSpecs[name] = Spec{valueName, help, defaultValue, required};
  return *this;
}

ArgParser& ArgParser::repeated(const std::string& name, const std::string& valueName, int words,
                               const std::string& help) {
  mOrder.push_back(name);
  Spec spec{valueName, help, "", false};
  spec.words = words;
  spec.repeated = true;
  mSpecs[name] = spec;
  return *this;
}

ArgParser& ArgParser::flag(const std::string& name, const std::string& help) {
  mOrder.push_back(name);
  mSpecs[name] = Spec{"", help, "", false};
  return *this;
}

namespace {

/// --help text of a setting: its help, unit and what 0 means (a flag says what it turns off).
std::string settingHelp(const Setting& setting) {
  std::string help = setting.help;
  if (setting.type == SettingType::kBool) {
    const bool on = std::get<bool>(defaultSettingValue(setting));
    return (on ? "turns off " : "turns on ") + help;
  }
  if (*setting.unit != '\0') {
    help += std::string(" (") + setting.unit + ")";
  }
  if (*setting.zero != '\0') {
    help += std::string(" (0 = ") + setting.zero + ")";
  }
  return help;
}

}  // namespace

ArgParser& ArgParser::settings(std::initializer_list<const char*> keys) {
  std::vector<const Setting*> chosen;
  for (const char* key : keys) {
    chosen.push_back(&findSetting(key));
  }
  if (keys.size() == 0) {
    for (const Setting& setting : settingsTable()) {
      const bool evaluatorOrBake =
          setting.scope == SettingScope::kEvaluator || setting.scope == SettingScope::kBake;
      if (setting.flag != nullptr && evaluatorOrBake) {
        chosen.push_back(&setting);
      }
    }
  }
  return declareSettings(chosen);
}

ArgParser& ArgParser::settings(SettingScope scope) {
  std::vector<const Setting*> chosen;
  for (const Setting* setting : settingsOfScope(scope)) {
    if (setting->flag != nullptr) {
      chosen.push_back(setting);
    }
  }
  return declareSettings(chosen);
}

ArgParser& ArgParser::declareSettings(const std::vector<const Setting*>& chosen) {
  for (const Setting* setting : chosen) {
    if (setting->flag == nullptr) {
      DS_THROW(kInternal, "the setting ", setting->key, " has no command-line flag");
    }
    mSettings.push_back(setting);
    if (setting->type == SettingType::kBool) {
      flag(setting->flag, settingHelp(*setting));
    } else {
      option(setting->flag, setting->valueName, settingHelp(*setting),
             formatSettingValue(*setting, defaultSettingValue(*setting)));
    }
  }
  return *this;
}

ArgParser& ArgParser::epilog(const std::string& text) {
  mEpilog = text;
  return *this;
}

ArgParser& ArgParser::positional(const std::string& names, int count) {
  mPositionalNames = names;
  mPositionalCount = count;
  return *this;
}

bool ArgParser::parse(const std::vector<std::string>& args) {
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& word = args[i];
    if (word == "-h" || word == "--help") {
      return false;
    }
    if (word.size() > 1 && word[0] == '-' && !(word.size() > 1 && std::isdigit(word[1]))) {
      std::string name = word;
      std::string value;
      bool inlineValue = false;
      if (const auto eq = word.find('='); eq != std::string::npos) {
        name = word.substr(0, eq);
        value = word.substr(eq + 1);
        inlineValue = true;
      }
      const auto spec = mSpecs.find(name);
      if (spec == mSpecs.end()) {
        DS_THROW(kUsage, "unknown option '", name, "' for `", mUsage, "`; see --help");
      }
      if (spec->second.repeated) {
        const int words = spec->second.words;
        if (inlineValue && words != 1) {
          DS_THROW(kUsage, "option '", name, "' takes ", words, " values (", spec->second.valueName,
                   "), not name=value");
        }
        std::vector<std::string> values;
        if (inlineValue) {
          values.push_back(value);
        }
        while (static_cast<int>(values.size()) < words) {
          const bool option = i + 1 < args.size() && args[i + 1].size() > 1 &&
                              args[i + 1][0] == '-' && !std::isdigit(args[i + 1][1]);
          if (i + 1 >= args.size() || option) {
            DS_THROW(kUsage, "option '", name, "' needs ", words, words == 1 ? " value" : " values",
                     " (", spec->second.valueName, ")");
          }
          values.push_back(args[++i]);
        }
        mRepeated[name].push_back(std::move(values));
        continue;
      }
      if (spec->second.valueName.empty()) {
        if (inlineValue) {
          DS_THROW(kUsage, "option '", name, "' takes no value");
        }
        mValues[name] = "1";
        continue;
      }
      if (!inlineValue) {
        if (i + 1 >= args.size()) {
          DS_THROW(kUsage, "option '", name, "' needs a value (", spec->second.valueName, ")");
        }
        value = args[++i];
      }
      mValues[name] = value;
      continue;
    }
    mPositionals.push_back(word);
  }
  if (static_cast<int>(mPositionals.size()) != mPositionalCount) {
    if (mPositionalCount == 0) {
      DS_THROW(kUsage, "unexpected argument '", mPositionals.front(), "' for `", mUsage,
               "`; see --help");
    }
    DS_THROW(kUsage, "`", mUsage, "` takes ", mPositionalNames, "; see --help");
  }
  for (const auto& name : mOrder) {
    const Spec& spec = mSpecs.at(name);
    if (spec.required && mValues.count(name) == 0) {
      DS_THROW(kUsage, "missing required option ", name, " ", spec.valueName, " for `", mUsage,
               "`; see --help");
    }
  }
  return true;
}

std::string ArgParser::help() const {
  std::ostringstream out;
  out << "usage: " << mUsage << "\n\n" << mSummary << "\n";
  if (!mOrder.empty()) {
    out << "\noptions:\n";
  }
  for (const auto& name : mOrder) {
    const Spec& spec = mSpecs.at(name);
    std::string left = "  " + name;
    if (!spec.valueName.empty()) {
      left += " " + spec.valueName;
    }
    out << left;
    if (left.size() < 28) {
      out << std::string(28 - left.size(), ' ');
    } else {
      out << "\n" << std::string(28, ' ');
    }
    out << spec.help;
    if (spec.repeated) {
      out << " (repeatable)";
    } else if (spec.required) {
      out << " (required)";
    } else if (!spec.defaultValue.empty()) {
      out << " [default: " << spec.defaultValue << "]";
    }
    out << "\n";
  }
  out << "  -h, --help                show this help\n";
  if (!mEpilog.empty()) {
    out << "\n" << mEpilog << "\n";
  }
  return out.str();
}

bool ArgParser::has(const std::string& name) const {
  return mValues.count(name) != 0 || mRepeated.count(name) != 0;
}

std::vector<std::vector<std::string>> ArgParser::all(const std::string& name) const {
  const auto it = mRepeated.find(name);
  return it == mRepeated.end() ? std::vector<std::vector<std::string>>() : it->second;
}

std::string ArgParser::get(const std::string& name) const {
  const auto it = mValues.find(name);
  if (it != mValues.end()) {
    return it->second;
  }
  return mSpecs.at(name).defaultValue;
}

int ArgParser::getInt(const std::string& name, int minimum) const {
  const std::string text = get(name);
  char* end = nullptr;
  errno = 0;
  const long value = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno != 0 || value < minimum || value > 1000000000L) {
    DS_THROW(kUsage, "option ", name, " takes a whole number >= ", minimum, " (got '", text, "')");
  }
  return static_cast<int>(value);
}

double ArgParser::getDouble(const std::string& name, double minimum) const {
  const std::string text = get(name);
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !(value >= minimum)) {
    DS_THROW(kUsage, "option ", name, " takes a number >= ", minimum, " (got '", text, "')");
  }
  return value;
}

std::string absolute(const std::string& path) {
  std::error_code ec;
  const auto full = std::filesystem::absolute(path, ec);
  return ec ? path : full.lexically_normal().string();
}

std::vector<NamedPath> givenPaths(const ArgParser& parser,
                                  std::initializer_list<const char*> options, bool sequences) {
  std::vector<NamedPath> paths;
  for (const char* option : options) {
    if (parser.has(option)) {
      const std::string value = parser.get(option);
      paths.push_back({option, value, sequences && hasFramePattern(value)});
    }
  }
  return paths;
}

void createOutputFoldersFor(const std::vector<std::string>& paths, bool quiet) {
  for (const std::string& path : paths) {
    for (const std::string& folder : createOutputFolders(path)) {
      if (!quiet) {
        std::cerr << "created folder " << absolute(folder) << "\n";
      }
    }
  }
}

namespace {

/// Sets every settings option given through `set`; returns the keys of those given.
template <typename Set>
std::vector<std::string> readGiven(const ArgParser& parser, Set&& set) {
  std::vector<std::string> given;
  for (const Setting* setting : parser.declaredSettings()) {
    if (!parser.has(setting->flag)) {
      continue;
    }
    // A flag sets the other value than the default (--no-resolve).
    const SettingValue value = setting->type == SettingType::kBool
                                   ? SettingValue(!std::get<bool>(defaultSettingValue(*setting)))
                                   : parseSettingValue(*setting, parser.get(setting->flag));
    set(*setting, value);
    given.emplace_back(setting->key);
  }
  return given;
}

}  // namespace

void readSettings(const ArgParser& parser, BakeOptions& options) {
  const std::vector<std::string> given =
      readGiven(parser, [&](const Setting& setting, const SettingValue& value) {
        setSetting(setting, options, value);
      });
  refuseUnusedSettings(unusedSettings({options.evaluator, &options}, given));
}

void readSettings(const ArgParser& parser, EvaluatorSettings& settings) {
  const std::vector<std::string> given =
      readGiven(parser, [&](const Setting& setting, const SettingValue& value) {
        setSetting(setting, settings, value);
      });
  refuseUnusedSettings(unusedSettings({settings}, given));
}

void readSettings(const ArgParser& parser, LayerOptions& options) {
  readGiven(parser, [&](const Setting& setting, const SettingValue& value) {
    if (setting.scope == SettingScope::kLayer) {
      setSetting(setting, options, value);
    }
  });
}

void readSettings(const ArgParser& parser, DatabaseBuildOptions& options) {
  readGiven(parser, [&](const Setting& setting, const SettingValue& value) {
    setSetting(setting, options, value);
  });
}

void readSettings(const ArgParser& parser, SimulationOptions& options) {
  readGiven(parser, [&](const Setting& setting, const SettingValue& value) {
    setSetting(setting, options, value);
  });
}

}  // namespace drivenshape::cli
