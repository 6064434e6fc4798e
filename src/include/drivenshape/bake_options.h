// SPDX-License-Identifier: Apache-2.0
#pragma once

// What a bake is asked to do (`drivenshape bake`'s options, BakeOptions): the frames, the
// outputs, the evaluator's settings and what the bake adds around them; and what simulating the
// frames its verdict flags is asked to do (`drivenshape simulate`'s settings, SimulationOptions).
// Plain data that the settings table reads and writes; the bake itself is drivenshape/bake.h,
// the simulation's plan and splice drivenshape/simulation.h.

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

/// Frames a cloth simulation runs before the first frame it is wanted for, so that the cloth
/// has settled from its start state: the default warm-up of a simulation window, and the run-up
/// of the bake report's simulate_runs. Chosen on the curve of docs/validation.md ("Simulated
/// windows"): warm-started from the bake with a free simulation, windows on four validation
/// clips came within 1.5 x the sim-to-sim spread of the full simulation in 5 of 8 cases with 5
/// frames, 6 with 10 or 20, and 7 with 40 (mean 1.12 x the spread).
inline constexpr int kDefaultSimulationWarmup = 40;

/// How the frames a bake's verdict flags are simulated and spliced back (`drivenshape simulate`,
/// drivenshape/simulation.h; the settings table's SettingScope::kSimulate rows). The warm-up
/// and the goal strength (0: a goal of 0.01 or more holds the cloth at the bake's own error)
/// come from the measured curve; merge gap, seam and carry are not measured.
struct SimulationOptions {
  /// Frames each window simulates before its first flagged frame (never before the shot's
  /// first frame), starting from the bake's cloth there.
  int warmup = kDefaultSimulationWarmup;
  /// Runs of flagged frames at most this many unflagged frames apart are one window (the
  /// frames between are simulated and handed back too): a short gap costs fewer frames than
  /// a second warm-up and two more seams.
  int mergeGap = 10;
  /// How strongly the simulation is pulled towards the bake (the cloth's pin goal in Blender):
  /// 0 = a free simulation, 1 = the bake.
  double goalStrength = 0.0;
  /// Frames before a window's first handed-back frame over which the output cross-fades from
  /// the bake to the simulation (within the warm-up).
  int seam = 4;
  /// Frames after a window's last frame over which the simulation's residual (simulated -
  /// baked) at that frame is carried forward onto the bake, fading to 0.
  int carry = 10;
  /// One window from the shot's first frame to its last flagged frame instead of warm-started
  /// windows: for cloth whose warm-started windows do not settle within a warm-up.
  bool fromStart = false;
};

}  // namespace drivenshape
