// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <drivenshape/layers.h>

#include "cli_args.h"

namespace drivenshape::cli {

/// Declares the layer flags (--mix, --mix-weight, --mix-falloff, --wind-*: the settings table's
/// SettingScope::kLayer rows) on a command's parser, with their units and defaults in --help.
/// A command adds layers with two lines:
///
///     addLayerFlags(parser);
///     ...parse...
///     const LayerOptions layers = readLayerFlags(parser, framesPerSecond);
void addLayerFlags(ArgParser& parser);

/// The parsed layer flags. `framesPerSecond` is the shot's rate (wind time = frame / fps).
/// Throws Error(kUsage) naming the flag for malformed values and values out of the table's
/// range; LayerStack checks how they go together.
LayerOptions readLayerFlags(const ArgParser& parser, double framesPerSecond);

}  // namespace drivenshape::cli
