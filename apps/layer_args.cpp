// SPDX-License-Identifier: Apache-2.0
#include "layer_args.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include <drivenshape/error.h>

namespace drivenshape::cli {
namespace {

constexpr const char* kMapForms =
    "a .json array with one number in [0, 1] per driven vertex, a one-channel point-cache .exr, "
    "or group:NAME[,NAME] (faces of the driven OBJ's groups)";

std::array<double, 3> parseDirection(const std::string& text) {
  std::array<double, 3> direction{};
  std::stringstream stream(text);
  std::string part;
  int count = 0;
  while (std::getline(stream, part, ',')) {
    char* end = nullptr;
    errno = 0;
    const double value = std::strtod(part.c_str(), &end);
    if (count >= 3 || part.empty() || *end != '\0' || errno != 0 || !std::isfinite(value)) {
      count = -1;
      break;
    }
    direction[static_cast<std::size_t>(count++)] = value;
  }
  if (count != 3) {
    DS_THROW(kUsage, "--wind-direction takes X,Y,Z, three numbers (got '", text, "')");
  }
  return direction;
}

}  // namespace

void addLayerFlags(ArgParser& parser) {
  parser
      .option("--mix", "CACHE",
              "mix the result per vertex with another cache of the driven mesh (a simulated "
              "hood, a skinned mesh): .pc2 or name.####.exr, every baked frame present")
      .option("--mix-weight", "MAP",
              std::string("where the DrivenShape result is kept (1) or the --mix cache taken "
                          "(0): ") +
                  kMapForms)
      .option("--mix-falloff", "RINGS",
              "soften the --mix-weight edge across this many edge rings (0 = hard edge)", "3")
      .option("--wind-amplitude", "UNITS",
              "procedural wind: largest displacement per axis, in scene units (0 = no wind)", "0")
      .option("--wind-frequency", "PER_UNIT",
              "noise cells per scene unit of the first octave (1/size of the largest gusts)", "1")
      .option("--wind-direction", "X,Y,Z", "direction the gusts travel (normalised)", "1,0,0")
      .option("--wind-speed", "UNITS_PER_S",
              "how fast the gusts travel, scene units per second (0 = a still pattern)", "1")
      .option("--wind-octaves", "N", "noise octaves 1..8, each twice as fine and half as strong",
              "3")
      .option("--wind-seed", "N", "noise seed (another seed, another wind)", "1")
      .option("--wind-weight", "MAP",
              std::string("where the wind blows (1) or not (0), default everywhere: ") + kMapForms)
      .option("--wind-falloff", "RINGS", "soften the --wind-weight edge across this many rings",
              "0");
}

LayerOptions readLayerFlags(const ArgParser& parser, double framesPerSecond) {
  LayerOptions options;
  if (parser.has("--mix")) {
    options.mixCache = parser.get("--mix");
  }
  if (parser.has("--mix-weight")) {
    options.mixWeight = parser.get("--mix-weight");
  }
  options.mixFalloff = parser.getInt("--mix-falloff", 0);
  options.windAmplitude = parser.getDouble("--wind-amplitude", 0.0);
  options.windFrequency = parser.getDouble("--wind-frequency", 0.0);
  options.windDirection = parseDirection(parser.get("--wind-direction"));
  options.windSpeed = parser.getDouble("--wind-speed", 0.0);
  options.windOctaves = parser.getInt("--wind-octaves", 1);
  options.windSeed = static_cast<std::uint32_t>(parser.getInt("--wind-seed", 0));
  if (parser.has("--wind-weight")) {
    options.windWeight = parser.get("--wind-weight");
  }
  options.windFalloff = parser.getInt("--wind-falloff", 0);
  options.framesPerSecond = framesPerSecond;
  return options;
}

}  // namespace drivenshape::cli
