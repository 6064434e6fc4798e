// SPDX-License-Identifier: Apache-2.0
// Evaluates a shot in memory through the installed library and compares every frame, bitwise,
// with the command line's bake of the same frames.
//
//   consumer DB DRIVER_CACHE BAKE_PATTERN FIRST LAST

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/database.h>
#include <drivenshape/device.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/point_cache.h>

int main(int argc, char** argv) {
  if (argc != 6) {
    std::fprintf(stderr, "usage: consumer DB DRIVER_CACHE BAKE_PATTERN FIRST LAST\n");
    return 2;
  }
  try {
    const drivenshape::Database db = drivenshape::loadDatabase(argv[1]);
    std::vector<int> frames;
    for (int f = std::atoi(argv[4]); f <= std::atoi(argv[5]); ++f) {
      frames.push_back(f);
    }
    const std::vector<float> driver =
        drivenshape::readFrames(*drivenshape::openPointCache(argv[2]), frames);

    std::unique_ptr<drivenshape::Device> device = drivenshape::openDevice("cpu");
    drivenshape::Evaluator evaluator(db, drivenshape::EvaluatorSettings(), *device);
    const drivenshape::Evaluation out = evaluator.evaluate(frames, driver);

    const std::vector<float> baked =
        drivenshape::readFrames(*drivenshape::openPointCache(argv[3]), frames);
    if (baked.size() != out.cloth.size()) {
      std::fprintf(stderr, "consumer: %zu values evaluated, %zu baked\n", out.cloth.size(),
                   baked.size());
      return 1;
    }
    std::size_t differing = 0;
    for (std::size_t i = 0; i < baked.size(); ++i) {
      differing += std::memcmp(&baked[i], &out.cloth[i], sizeof(float)) != 0 ? 1 : 0;
    }
    std::printf("consumer: %zu frames on %s, %zu of %zu values differ from the CLI bake\n",
                frames.size(), evaluator.deviceName().c_str(), differing, baked.size());
    return differing == 0 ? 0 : 1;
  } catch (const drivenshape::Error& error) {
    std::fprintf(stderr, "consumer: %s\n", error.what());
    return 1;
  }
}
