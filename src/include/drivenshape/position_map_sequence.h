// SPDX-License-Identifier: Apache-2.0
#pragma once

// Position maps of a whole sequence: rasterise once, evaluate frames on a device, write the EXRs
// (and previews). The `posmap` command and embedders call it.

#include <functional>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/position_map.h>
#include <drivenshape/position_map_backend.h>
#include <drivenshape/position_map_tables.h>

namespace drivenshape {

/// Writes position maps of one mesh frame by frame: rasterises once, evaluates on a backend,
/// writes EXRs (and previews). The bake calls it after blending, the `posmap` command after
/// reading a cache.
///
///     PositionMapWriter writer(mesh, options, makeHostPositionMaps(), "cloth.obj", &std::cerr);
///     writer.writeFrame(1001, xyz, "maps/cloth.1001.exr");
///
/// A map whose tables pass 4 * options.launchBytes (PositionMapOptions) is banded: each launch
/// rasterises, evaluates and writes it a band of rows at a time (PositionMapRaster,
/// PositionMapExrWriter), so that memory stays near options.launchBytes however large the map.
/// The files are the same bytes either way.
class PositionMapWriter {
 public:
  /// Builds the tables (buildPositionMapTables: may throw kUsage / kInput) and uploads them; a
  /// banded map counts its texels and overlaps band by band instead (tables() has no texels).
  /// An overlap of UV islands is reported on `log` as a warning line (when `log` is set).
  PositionMapWriter(const Mesh& mesh, const PositionMapOptions& options,
                    std::unique_ptr<PositionMapBackend> backend,
                    const std::string& meshName = "mesh", std::ostream* log = nullptr);
  ~PositionMapWriter();
  PositionMapWriter(const PositionMapWriter&) = delete;
  PositionMapWriter& operator=(const PositionMapWriter&) = delete;

  /// The map's tables; for a banded map its sizes, triangles and counts only (no texels).
  const PositionMapTables& tables() const { return mTables; }
  /// Whether the map is written a band of rows at a time (see above).
  bool banded() const { return mRaster != nullptr; }
  const PositionMapOptions& options() const { return mOptions; }
  std::string backendName() const;
  /// Frames per writeFrames() call that one launch handles (from options and memory).
  int chunkSize() const { return mChunkSize; }

  /// One frame: `xyz` holds 3V floats of the mesh's vertices.
  void writeFrame(int frame, const float* xyz, const std::string& path);
  /// Several frames: `xyz` is F x 3V (frame-major), `paths[f]` the output of `frames[f]`.
  /// Frames beyond chunkSize() are split into several launches. Files are written on up to
  /// options.threads threads; a failed file does not stop the others, and the first failure
  /// is rethrown after the rest are written.
  void writeFrames(const std::vector<int>& frames, const float* xyz,
                   const std::vector<std::string>& paths);

  /// Seconds spent so far in evaluation (backend) and in writing files.
  double evaluateSeconds() const { return mEvaluateSeconds; }
  double writeSeconds() const { return mWriteSeconds; }

 private:
  struct Chunk;
  void writeChunk(int count, const int* frames, const float* xyz, const std::string* paths);
  /// Evaluates and writes rows [firstRow, firstRow + rows) of every map of `chunk`.
  void writeBand(Chunk& chunk, int firstRow, int rows);
  /// Rows per band of a launch of `frames` frames (the height when the map is not banded).
  int bandRows(int frames) const;

  PositionMapOptions mOptions;
  std::unique_ptr<PositionMapRaster> mRaster;  ///< banded maps only
  PositionMapTables mTables;
  std::unique_ptr<PositionMapBackend> mBackend;
  int mChunkSize = 1;
  std::vector<float> mPositions;
  std::vector<float> mNormals;
  double mEvaluateSeconds = 0.0;
  double mWriteSeconds = 0.0;
};

/// What writePositionMapSequence did.
struct PositionMapRunResult {
  int written = 0;
  double readSeconds = 0.0;
  double evaluateSeconds = 0.0;
  double writeSeconds = 0.0;
  double totalSeconds = 0.0;
};

/// Writes the maps of `frames` of `cache` to `outputPattern` (a frame token, e.g.
/// maps/cloth.####.exr), a chunk of frames at a time. Checks first that the cache has the
/// mesh's vertex count and every frame (Error(kInput) naming the cache, the counts or the
/// missing frames) and that the output folder is writable (Error(kOutput)).
/// `frameDone(frame, path)` is called after each file, on the calling thread.
PositionMapRunResult writePositionMapSequence(
    PositionMapWriter& writer, const PointCacheReader& cache, const std::vector<int>& frames,
    const std::string& outputPattern,
    const std::function<void(int, const std::string&)>& frameDone = {});

}  // namespace drivenshape
