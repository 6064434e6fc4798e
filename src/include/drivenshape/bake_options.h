// SPDX-License-Identifier: Apache-2.0
#pragma once

// What a bake is asked to do (`drivenshape bake`'s options, BakeOptions): the frames, the
// outputs, the evaluator's settings and what the bake adds around them. Plain data that the
// settings table reads and writes; the bake itself is drivenshape/bake.h.

#include <cstddef>
#include <string>
#include <vector>

#include <drivenshape/evaluator.h>
#include <drivenshape/layers.h>
#include <drivenshape/point_cache.h>

namespace drivenshape {

/// The bake's defaults (`--batch`, `--temporal-warmup`; BakeOptions), which every tool uses.
inline constexpr int kDefaultBatchFrames = 64;
inline constexpr int kDefaultTemporalWarmup = 8;

/// Memory that one launch batch's frame blocks may take; larger meshes get smaller batches
/// (see shotPlanSettings).
inline constexpr std::size_t kBatchMemoryBudget = std::size_t(768) << 20;

struct BakeOptions {
  std::vector<int> frames;  ///< frames of the driver cache to bake
  /// The whole shot when `frames` is a part of it (a farm chunk), else empty (the shot is
  /// `frames`). The batches are planned over the shot, so a part's frames are the whole
  /// bake's for any chunking, and the verdict's simulation runs may start before the part.
  std::vector<int> shotFrames;
  std::string outputPattern;  ///< EXR sequence with a frame token, e.g. out/cloth.####.exr
  std::string reportPath;     ///< per-bake JSON report; empty = none
  /// Frames per kernel launch (`--batch`); lowered for large meshes so that a batch's buffers
  /// stay within kBatchMemoryBudget, except with the temporal bound (which depends on it).
  /// The batches are planShot's (drivenshape/shot_plan.h).
  int batchFrames = kDefaultBatchFrames;
  int threads = 0;            ///< host threads (QP, EXR); 0 = all cores
  bool skipExisting = false;  ///< keep complete outputs of this database and settings
  int exrWidth = 1024;
  ExrCompression compression = ExrCompression::kZip;
  ZipEncoder zipEncoder = ZipEncoder::kLibdeflate;  ///< of the caches and the position maps
  double framesPerSecond = 24.0;
  /// Every evaluator setting but the three that come from files here (see
  /// drivenshape/evaluator.h; `threads` is set from the bake's own): weights, alignment, blend,
  /// correction, resolution, temporal bound, audit. The defaults are the command line's.
  EvaluatorSettings evaluator;
  /// Binding mask file (see readBindingMask); empty = evaluator.bindingMask (every triangle
  /// when that is empty too).
  std::string bindingMaskPath;
  /// Region file (see readRegions); empty = evaluator.regions (one QP on every driver row when
  /// that is empty too).
  std::string regionsPath;
  /// With the temporal bound (evaluator.maxWeightChange > 0) frames are solved in order within
  /// each launch batch (`batchFrames` frames); before each batch, `temporalWarmup` driver-cache
  /// frames preceding its first frame are solved (the first of them without the bound) but not
  /// written. The output therefore depends on batchFrames and temporalWarmup, never on the thread
  /// count; a farm chunk (shotFrames) and a resume plan the shot's batches, so they reproduce
  /// the single bake exactly.
  int temporalWarmup = kDefaultTemporalWarmup;
  /// Layers after the correction and resolution (docs/commands.md, "Layering"): a mix with
  /// another cache of the cloth, procedural wind, from files. Off by default. Recorded in the
  /// settings hash, the report and the EXR header (`dsLayers`).
  LayerOptions layers;
  /// fsync every output EXR before its atomic rename (`--sync`). Off by default: the rename
  /// alone already means readers never see a partial file, and a file cut short by a power
  /// loss is rebaked by --skip-existing; the fsync costs a disk (or NFS) round trip per frame.
  bool syncOutputs = false;
  /// Bake a driver that checkDriver (drivenshape/driver_check.h) refuses: another scale than
  /// the database's, or edges that do not correspond (`--force`). Its findings become warnings.
  bool force = false;
  /// Why the database's driver mesh is baked untrusted: the warning of checkDriverMesh
  /// (drivenshape/mesh_check.h) for a driver that is not a closed, consistently oriented
  /// surface, set by admitDriverMesh with `--untrusted-driver`; empty for a driver that passes.
  /// The bake lists it among its warnings and the report's settings say `untrusted_driver`.
  std::string untrustedDriver;
};

}  // namespace drivenshape
