// SPDX-License-Identifier: Apache-2.0
// apps/layer_args.cpp: the layer flags a command gets with addLayerFlags, their defaults (as
// documented in --help) and the values they refuse.

#include "layer_args.h"

#include <drivenshape/error.h>

#include "io_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

cli::ArgParser parser() {
  cli::ArgParser parser("drivenshape test", "layer flags");
  cli::addLayerFlags(parser);
  return parser;
}

TEST(LayerArgs, DefaultsMatchLayerOptionsAndHelpListsEveryFlag) {
  cli::ArgParser p = parser();
  ASSERT_TRUE(p.parse({}));
  const LayerOptions options = cli::readLayerFlags(p, 25.0);
  const LayerOptions defaults;
  EXPECT_FALSE(options.hasMix());
  EXPECT_FALSE(options.hasWind());
  EXPECT_EQ(options.mixFalloff, defaults.mixFalloff);
  EXPECT_EQ(options.windFrequency, defaults.windFrequency);
  EXPECT_EQ(options.windDirection, defaults.windDirection);
  EXPECT_EQ(options.windSpeed, defaults.windSpeed);
  EXPECT_EQ(options.windOctaves, defaults.windOctaves);
  EXPECT_EQ(options.windSeed, defaults.windSeed);
  EXPECT_EQ(options.windFalloff, defaults.windFalloff);
  EXPECT_EQ(options.framesPerSecond, 25.0);
  const std::string help = p.help();
  for (const char* flag : {"--mix ", "--mix-weight", "--mix-falloff", "--wind-amplitude",
                           "--wind-frequency", "--wind-direction", "--wind-speed", "--wind-octaves",
                           "--wind-seed", "--wind-weight", "--wind-falloff"}) {
    EXPECT_TRUE(contains(help, flag));
  }
  EXPECT_TRUE(contains(help, "scene units"));
}

TEST(LayerArgs, ParsesEveryFlag) {
  cli::ArgParser p = parser();
  ASSERT_TRUE(p.parse({"--mix",
                       "skin.pc2",
                       "--mix-weight",
                       "group:waist",
                       "--mix-falloff",
                       "5",
                       "--wind-amplitude",
                       "0.01",
                       "--wind-frequency",
                       "4",
                       "--wind-direction",
                       "0,-1,0.5",
                       "--wind-speed",
                       "2.5",
                       "--wind-octaves",
                       "2",
                       "--wind-seed",
                       "42",
                       "--wind-weight",
                       "legs.json",
                       "--wind-falloff",
                       "2"}));
  const LayerOptions o = cli::readLayerFlags(p, 24.0);
  EXPECT_EQ(o.mixCache, "skin.pc2");
  EXPECT_EQ(o.mixWeight, "group:waist");
  EXPECT_EQ(o.mixFalloff, 5);
  EXPECT_EQ(o.windAmplitude, 0.01);
  EXPECT_EQ(o.windFrequency, 4.0);
  EXPECT_EQ(o.windDirection, (std::array<double, 3>{0.0, -1.0, 0.5}));
  EXPECT_EQ(o.windSpeed, 2.5);
  EXPECT_EQ(o.windOctaves, 2);
  EXPECT_EQ(o.windSeed, 42u);
  EXPECT_EQ(o.windWeight, "legs.json");
  EXPECT_EQ(o.windFalloff, 2);
}

TEST(LayerArgs, MalformedValuesAreUsageErrorsNamingTheFlag) {
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"--wind-direction", "1,0"},
        std::vector<std::string>{"--wind-direction", "1,0,x"},
        std::vector<std::string>{"--wind-direction", "1,0,0,0"},
        std::vector<std::string>{"--wind-amplitude", "-0.1"},
        std::vector<std::string>{"--wind-octaves", "0"},
        std::vector<std::string>{"--mix-falloff", "two"}}) {
    cli::ArgParser p = parser();
    ASSERT_TRUE(p.parse(args));
    const Error error = catchError([&] { cli::readLayerFlags(p, 24.0); });
    EXPECT_EQ(error.code(), ErrorCode::kUsage) << args[0] << " " << args[1];
    EXPECT_TRUE(contains(error.what(), args[0]));
  }
}

}  // namespace
}  // namespace drivenshape::testing
