// SPDX-License-Identifier: Apache-2.0
#include "layer_args.h"

namespace drivenshape::cli {

void addLayerFlags(ArgParser& parser) {
  parser.settings(SettingScope::kLayer);
}

LayerOptions readLayerFlags(const ArgParser& parser, double framesPerSecond) {
  LayerOptions options;
  readSettings(parser, options);
  options.framesPerSecond = framesPerSecond;
  return options;
}

}  // namespace drivenshape::cli
