// SPDX-License-Identifier: Apache-2.0
// The layers of one bake: settings validated, weight maps and the mix cache loaded once, then
// mix and wind applied to every chunk after the correction.

#include <drivenshape/layers.h>

#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>

#include <layer_types.h>
#include "hash.h"
#include "json_text.h"

namespace drivenshape {
namespace {

void checkFinite(double value, const char* flag) {
  if (!std::isfinite(value)) {
    DS_THROW(kUsage, flag, " must be a finite number (got ", value, ")");
  }
}

void validate(const LayerOptions& options) {
  if (options.hasMix() && options.mixWeight.empty()) {
    DS_THROW(kUsage, "the mix cache ", options.mixCache,
             " needs a mix weight map (1 keeps DrivenShape, 0 takes the mix cache)");
  }
  if (!options.hasMix() && !options.mixWeight.empty()) {
    DS_THROW(kUsage, "a mix weight map needs a mix cache (the cache to mix with)");
  }
  if (options.mixFalloff < 0 || options.mixFalloff > 64) {
    DS_THROW(kUsage, "the mix falloff ", options.mixFalloff, " must be 0..64 edge rings");
  }
  if (options.windFalloff < 0 || options.windFalloff > 64) {
    DS_THROW(kUsage, "the wind falloff ", options.windFalloff, " must be 0..64 edge rings");
  }
  checkFinite(options.windAmplitude, "the wind amplitude");
  checkFinite(options.windFrequency, "the wind frequency");
  checkFinite(options.windSpeed, "the wind speed");
  if (options.windAmplitude < 0.0) {
    DS_THROW(kUsage, "the wind amplitude ", options.windAmplitude,
             " must be >= 0 (scene units; 0 = no wind)");
  }
  if (!options.hasWind() && !options.windWeight.empty()) {
    DS_THROW(kUsage, "a wind weight map needs a wind amplitude > 0");
  }
  if (!(options.framesPerSecond > 0.0) || !std::isfinite(options.framesPerSecond)) {
    DS_THROW(kUsage, "frames per second ", options.framesPerSecond, " must be positive");
  }
  if (!options.hasWind()) {
    return;
  }
  if (!(options.windFrequency > 0.0)) {
    DS_THROW(kUsage, "the wind frequency ", options.windFrequency,
             " must be > 0 (noise cells per scene unit)");
  }
  if (options.windSpeed < 0.0) {
    DS_THROW(kUsage, "the wind speed ", options.windSpeed,
             " must be >= 0 (scene units per second; 0 = a still pattern)");
  }
  if (options.windOctaves < 1 || options.windOctaves > DS_WIND_MAX_OCTAVES) {
    DS_THROW(kUsage, "the wind octaves ", options.windOctaves, " must be 1..", DS_WIND_MAX_OCTAVES);
  }
  double length2 = 0.0;
  for (double value : options.windDirection) {
    checkFinite(value, "the wind direction");
    length2 += value * value;
  }
  if (!(length2 > 0.0)) {
    DS_THROW(kUsage, "the wind direction must not be 0,0,0 (give X,Y,Z, e.g. 1,0,0)");
  }
}

/// Rest positions minus their bounding-box centre: small coordinates keep the noise precise.
std::vector<float> centredRest(const Mesh& mesh) {
  const int count = mesh.vertexCount();
  const Bounds bounds = computeBounds(mesh.positions.data(), count);
  const Eigen::Vector3f centre = 0.5f * (bounds.min + bounds.max);
  std::vector<float> rest(3 * static_cast<std::size_t>(count));
  for (int v = 0; v < count; ++v) {
    for (int a = 0; a < 3; ++a) {
      rest[3 * static_cast<std::size_t>(v) + static_cast<std::size_t>(a)] =
          mesh.positions(v, a) - centre[a];
    }
  }
  return rest;
}

void hashFloats(Hasher& hasher, const std::vector<float>& values) {
  hasher.addValue(static_cast<std::uint64_t>(values.size()));
  hasher.add(values.data(), values.size() * sizeof(float));
}

}  // namespace

LayerSettings loadLayers(const LayerOptions& options, const Mesh& drivenMesh) {
  validate(options);
  LayerSettings settings;
  settings.options = options;
  if (options.hasMix()) {
    settings.mixWeights =
        smoothWeightMap(readWeightMap(options.mixWeight, drivenMesh, "mix weight map"), drivenMesh,
                        options.mixFalloff);
    settings.mixCache = openPointCache(options.mixCache, topologyHash(drivenMesh));
  }
  if (options.hasWind() && !options.windWeight.empty()) {
    settings.windWeights =
        smoothWeightMap(readWeightMap(options.windWeight, drivenMesh, "wind weight map"),
                        drivenMesh, options.windFalloff);
  }
  return settings;
}

LayerStack::LayerStack(LayerSettings settings, const Mesh& drivenMesh, LayerBackend& backend)
    : mOptions(std::move(settings.options)),
      mMixCache(std::move(settings.mixCache)),
      mBackend(backend) {
  const std::size_t vertices = static_cast<std::size_t>(drivenMesh.vertexCount());
  if (mMixCache) {
    // NaN in the other cache means "not simulated here" (a hood simulation need not cover the
    // legs): a NaN where the weight map takes the other cache is refused when its frames are
    // read, naming the vertex.
    mMixCache->allowNonFinite();
    if (mOptions.mixCache.empty()) {
      mOptions.mixCache = "(in memory)";
    }
    if (mOptions.mixWeight.empty()) {
      mOptions.mixWeight = "(in memory)";
    }
  } else {
    mOptions.mixCache.clear();
    mOptions.mixWeight.clear();
  }
  if (mOptions.hasWind() && mOptions.windWeight.empty() && !settings.windWeights.empty()) {
    mOptions.windWeight = "(in memory)";
  }
  validate(mOptions);
  mTables.vertexCount = drivenMesh.vertexCount();
  if (empty()) {
    return;
  }
  mTables.rest = centredRest(drivenMesh);
  if (mMixCache) {
    if (mMixCache->vertexCount() != drivenMesh.vertexCount()) {
      DS_THROW(kInput, "mix cache ", mOptions.mixCache, ": the cache has ",
               mMixCache->vertexCount(), " vertices but the driven mesh has ",
               drivenMesh.vertexCount(),
               "; mix with a cache of the same garment (same vertex count and order)");
    }
    if (settings.mixWeights.size() != vertices) {
      DS_THROW(kUsage, "the mix weights have ", settings.mixWeights.size(),
               " values but the driven mesh has ", vertices, " vertices");
    }
    mTables.mixWeights = std::move(settings.mixWeights);
  }
  if (mOptions.hasWind()) {
    if (!settings.windWeights.empty() && settings.windWeights.size() != vertices) {
      DS_THROW(kUsage, "the wind weights have ", settings.windWeights.size(),
               " values but the driven mesh has ", vertices, " vertices");
    }
    mTables.windWeights = settings.windWeights.empty() ? std::vector<float>(vertices, 1.0f)
                                                       : std::move(settings.windWeights);
    double length = 0.0;
    for (double value : mOptions.windDirection) {
      length += value * value;
    }
    length = std::sqrt(length);
    mWind.amplitude = static_cast<float>(mOptions.windAmplitude);
    mWind.frequency = static_cast<float>(mOptions.windFrequency);
    for (std::size_t a = 0; a < 3; ++a) {
      mWind.direction[a] = mOptions.windDirection[a] / length;
    }
    mWind.speed = mOptions.windSpeed;
    mWind.octaves = mOptions.windOctaves;
    mWind.seed = mOptions.windSeed;
    mWind.framesPerSecond = mOptions.framesPerSecond;
  }
  mBackend.upload(mTables);
}

bool LayerStack::empty() const {
  return !mOptions.hasMix() && !mOptions.hasWind();
}

void LayerStack::checkFrames(const std::vector<int>& frames) const {
  if (!mMixCache) {
    return;
  }
  for (int frame : frames) {
    if (!mMixCache->hasFrame(frame)) {
      const std::vector<int> has = mMixCache->frames();
      DS_THROW(kInput, "mix cache ", mOptions.mixCache, ": frame ", frame,
               " is missing; the mix cache holds ",
               has.empty() ? std::string("no frames") : "frames " + formatFrameRange(has),
               "; mix with a cache that covers every baked frame");
    }
  }
}

void LayerStack::apply(int frameCount, const int* frames, float* positions,
                       const float* clearance) {
  if (empty() || frameCount <= 0) {
    return;
  }
  if (mMixCache) {
    const std::size_t floats = 3 * static_cast<std::size_t>(mTables.vertexCount);
    mOther.resize(static_cast<std::size_t>(frameCount) * floats);
    for (int f = 0; f < frameCount; ++f) {
      const float* other = mOther.data() + static_cast<std::size_t>(f) * floats;
      mMixCache->readFrame(frames[f], mOther.data() + static_cast<std::size_t>(f) * floats);
      // Where the mix takes any of the other cache, its positions must be numbers.
      for (int v = 0; v < mTables.vertexCount; ++v) {
        if (mTables.mixWeights[v] < 1.0f &&
            !(std::isfinite(other[3 * v]) && std::isfinite(other[3 * v + 1]) &&
              std::isfinite(other[3 * v + 2]))) {
          DS_THROW(kInput, "mix cache ", mOptions.mixCache, ": frame ", frames[f], " vertex ", v,
                   " is not a finite number; fix the cache or give the vertex mix weight 1");
        }
      }
    }
    mBackend.mix(frameCount, mOther.data(), positions);
  }
  if (mOptions.hasWind()) {
    mBackend.wind(frameCount, frames, mWind, clearance, positions);
  }
}

void LayerStack::addToHash(Hasher& hasher) const {
  hasher.addString("drivenshape.layers.1");
  hasher.addValue(static_cast<std::uint8_t>(mOptions.hasMix() ? 1 : 0));
  if (mOptions.hasMix()) {
    // The file name and the loaded weights (after the falloff); the mix cache's content is not
    // read up front, so a rewritten cache under the same name needs a rebake by hand.
    hasher.addString(mOptions.mixCache);
    hashFloats(hasher, mTables.mixWeights);
  }
  hasher.addValue(static_cast<std::uint8_t>(mOptions.hasWind() ? 1 : 0));
  if (mOptions.hasWind()) {
    hasher.addValue(mWind.amplitude).addValue(mWind.frequency).addValue(mWind.speed);
    for (double value : mWind.direction) {
      hasher.addValue(value);
    }
    hasher.addValue(static_cast<std::int32_t>(mWind.octaves)).addValue(mWind.seed);
    hasher.addValue(mWind.framesPerSecond);
    hashFloats(hasher, mTables.windWeights);
  }
}

std::string LayerStack::describe() const {
  nlohmann::ordered_json json = nlohmann::ordered_json::object();
  if (mOptions.hasMix()) {
    json["mix"] = {{"cache", mOptions.mixCache},
                   {"weight", mOptions.mixWeight},
                   {"falloff", mOptions.mixFalloff}};
  }
  if (mOptions.hasWind()) {
    nlohmann::ordered_json wind = {
        {"amplitude", mOptions.windAmplitude}, {"frequency", mOptions.windFrequency},
        {"direction", mWind.direction},        {"speed", mOptions.windSpeed},
        {"octaves", mOptions.windOctaves},     {"seed", mOptions.windSeed}};
    if (!mOptions.windWeight.empty()) {
      wind["weight"] = mOptions.windWeight;
      wind["falloff"] = mOptions.windFalloff;
    }
    wind["fps"] = mOptions.framesPerSecond;
    json["wind"] = wind;
  }
  return jsonText(json);
}

}  // namespace drivenshape
