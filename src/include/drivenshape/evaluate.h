// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <string>
#include <vector>

#include <drivenshape/binding.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

namespace drivenshape {

class ClosestBackend;  // src/devices/closest.h, private
class Device;          // drivenshape/device.h

/// Per-vertex position error of a bake against a truth cache (metres, or the caches' unit).
struct FrameError {
  int frame = 0;
  double mean = 0, rms = 0, max = 0;
  int maxVertex = -1;  ///< the vertex where `max` occurs
};

struct EvaluationResult {
  std::vector<FrameError> frames;
  double mean = 0, rms = 0, max = 0;  ///< over all vertices of all frames
  int maxFrame = 0;
  int vertexCount = 0;
};

/// Compares two caches frame by frame. Throws Error(kInput) if the vertex counts differ or a
/// frame is missing from either.
EvaluationResult evaluateCaches(const PointCacheReader& truth, const PointCacheReader& baked,
                                const std::vector<int>& frames);

// ---- Strain: how far the cloth's edges stretch or shrink against its rest mesh ----

/// The |strain| limit of StrainFigures::overShare: 0.1, an edge 10% longer or shorter than at
/// rest.
constexpr double kStrainLimit = 0.1;

/// Figures of the |strain| of a set of edge values: one frame's edges, or every edge of every
/// frame of a shot (ClothMetrics::strain). An edge's strain is |edge| / |rest edge| - 1 (the
/// edge's length on the frame over its length on the rest mesh, less 1: +0.2 is stretched by
/// 20%, -0.2 shrunk by 20%).
///
/// The percentile, the one definition used everywhere (eval's table and JSON, the Python
/// module): the nearest-rank 95th percentile of the n values (a frame's: its n edges; a
/// shot's: every edge of every frame, n = edges x frames): the |strain| values sorted
/// ascending, the one at 1-based rank ceil(0.95 n). It is a value that occurs, and at least
/// 95% of the values are at most it.
struct StrainFigures {
  long long values = 0;    ///< values the figures cover (edges; edges x frames for a shot)
  double mean = 0.0;       ///< mean |strain|
  double p95 = 0.0;        ///< nearest-rank 95th percentile of |strain|
  double overShare = 0.0;  ///< share of the values with |strain| > kStrainLimit, in [0, 1]
};

/// The 1-based rank of the 95th percentile of n values: ceil(0.95 n), in integers (no
/// rounding); 0 for n = 0.
long long strainPercentileRank(long long n);

/// The strain of each edge of `edges` (vertex ids into both V x 3 blocks) on `positions`
/// against `rest`: |p[b] - p[a]| / |r[b] - r[a]| - 1, in double, in the order of `edges`.
/// Throws Error(kInput) for an edge naming a vertex outside [0, vertexCount) or of zero rest
/// length (no strain is defined for it).
std::vector<double> edgeStrains(const float* rest, const float* positions, int vertexCount,
                                const std::vector<MeshEdge>& edges);

/// The figures of one frame: edgeStrains, then the mean, the nearest-rank 95th percentile and
/// the share over kStrainLimit of their magnitudes (all 0 without edges). Throws as
/// edgeStrains.
StrainFigures frameStrain(const float* rest, const float* positions, int vertexCount,
                          const std::vector<MeshEdge>& edges);

// ---- Whole-shot evaluation (`drivenshape eval`): bake, truth and binding baseline ----

/// One cloth sequence's figures for one frame.
struct ClothFrameMetrics {
  int frame = 0;
  FrameError error;         ///< against the truth (all 0 for the truth itself)
  double jump = -1.0;       ///< largest vertex move since the previous frame of the list (scene
                            ///< units); -1 on the first frame
  int jumpVertex = -1;      ///< where `jump` occurs
  int inside = -1;          ///< vertices inside the shot's driver (signed distance < 0);
                            ///< -1 when not measured (no driver)
  double maxDepth = 0.0;    ///< the deepest of them (>= 0, scene units; 0 when none)
  int maxDepthVertex = -1;  ///< where `maxDepth` occurs (-1 when none is inside)
  StrainFigures strain;     ///< the frame's edges (all 0 when not measured)
};

/// One cloth sequence over the whole frame list.
struct ClothMetrics {
  std::string name;    ///< "bake", "truth" or "baseline"
  std::string source;  ///< the cache it was read from; empty for the baseline
  std::vector<ClothFrameMetrics> frames;
  double mean = 0, rms = 0, max = 0;  ///< error against the truth over all vertices and frames
  int maxFrame = 0;                   ///< frame of `max`
  double maxJump = -1.0;              ///< largest `jump` over the list (-1 with one frame)
  int maxJumpFrame = 0;               ///< the frame it leads to
  double meanInside = -1.0;           ///< `inside` averaged over the frames (-1: not measured)
  int maxInside = -1;                 ///< largest `inside` of a frame
  int maxInsideFrame = 0;
  double maxDepth = 0.0;  ///< deepest penetration over the list
  int maxDepthFrame = 0;
  /// Every edge of every frame of the list as one set of values (the percentile over all of
  /// them, not an average of the frames'); all 0 when not measured.
  StrainFigures strain;
};

/// What evaluateShot reads. The truth and the bake are required; the rest turns on metrics:
///
///   drivenMesh                          strain of every sequence (its faces' edges, its rest
///                                       positions)
///   driver + driverMesh                 penetrations of every sequence
///   driver + driverMesh + drivenMesh    and, with `baseline`, the binding baseline
///
/// The binding baseline is what `bake --weights bind --no-resolve` computes: the rest cloth
/// (drivenMesh positions) bound to the rest driver (driverMesh positions) at its exact closest
/// triangles (those `mask` allows; every triangle without a mask), carried to each frame's
/// driver by ClosestBackend::transfer.
struct ShotEvaluationInput {
  const PointCacheReader* truth = nullptr;
  const PointCacheReader* bake = nullptr;
  const PointCacheReader* driver = nullptr;  ///< the shot's driver cache
  const Mesh* driverMesh = nullptr;          ///< rest driver: topology, rest pose
  const Mesh* drivenMesh = nullptr;          ///< rest cloth (strain, baseline)
  std::string driverMeshName;                ///< where the meshes came from, for messages
  std::string drivenMeshName;
  bool baseline = false;
  const BindingMask* mask = nullptr;  ///< baseline binding mask; null = any triangle
  int batch = 16;                     ///< frames per backend call
  int threads = 0;                    ///< host threads for the inside test; 0 = all cores
  /// A driver mesh that checkDriverMesh refuses (open, non-manifold, inconsistently oriented:
  /// the inside test cannot be trusted) is evaluated without the penetration figures instead of
  /// refused (`eval --untrusted-driver`); the baseline is still measured.
  bool untrustedDriver = false;
};

struct ShotEvaluation {
  std::vector<int> frames;    ///< in the order given (jumps follow this order)
  int vertexCount = 0;        ///< cloth vertices
  int driverVertexCount = 0;  ///< 0 without a driver
  bool penetrations = false;  ///< whether `inside` and depths were measured
  /// Whether strain was measured: with a drivenMesh that has an edge of non-zero rest length.
  bool strain = false;
  int edgeCount = 0;  ///< the rest mesh's edges the strain covers (meshEdges of drivenMesh)
  /// Edges of drivenMesh left out of the strain for a zero rest length (coincident corners).
  int zeroLengthEdges = 0;
  /// checkDriverMesh's warning when the driver mesh was evaluated untrusted (no penetration
  /// figures); empty otherwise.
  std::string untrustedDriver;
  bool hasBaseline = false;
  ClothMetrics bake;
  ClothMetrics truth;
  ClothMetrics baseline;  ///< valid when hasBaseline
};

/// Evaluates a shot: per frame, the bake's (and the baseline's) error against the truth, the
/// largest frame-to-frame jump of every sequence, with the cloth's rest mesh the strain of
/// every sequence's edges (StrainFigures, per frame and over the shot), and with a driver the
/// vertices of every sequence inside it with the deepest one (exact closest triangle over every
/// triangle, then InsideAudit's signed distance). `closest` is any ClosestBackend (host or OpenCL);
/// its surface is set here. Throws Error(kUsage) for an empty frame list or a metric without the
/// inputs it needs, and Error(kInput) for mismatched vertex counts (the cloth's rest mesh
/// included), missing frames, non-finite positions or a driver mesh checkDriverMesh refuses (see
/// `untrustedDriver`).
ShotEvaluation evaluateShot(const ShotEvaluationInput& input, const std::vector<int>& frames,
                            ClosestBackend& closest);

/// The same on `device` (host or OpenCL), with a closest-triangle search of its own on
/// `input.threads` host threads: what `drivenshape eval` runs, and what an embedder calls.
ShotEvaluation evaluateShot(const ShotEvaluationInput& input, const std::vector<int>& frames,
                            Device& device);

}  // namespace drivenshape
