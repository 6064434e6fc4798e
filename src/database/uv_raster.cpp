// SPDX-License-Identifier: Apache-2.0
// UV rasterisation for position maps (the "far" side): texel -> triangle + barycentrics,
// built once per mesh and map size. See position_map.h for the conventions.

#include <drivenshape/position_map_tables.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <unordered_set>

#include <drivenshape/error.h>

namespace drivenshape {
// Named, not anonymous: classes declared in headers hold these types (GCC's
// -Wsubobject-linkage in unity builds).
namespace uv_raster_parts {

// Coverage is decided on UVs snapped to 1/256 texel, in 64-bit integers: exact, so the
// top-left rule below gives every texel centre on a shared edge to exactly one triangle.
// Coordinates stay below 2^14 * 2^8 = 2^22, edge-function products below 2^46.
constexpr int kSubpixelBits = 8;
constexpr std::int64_t kSubpixel = std::int64_t{1} << kSubpixelBits;
constexpr std::int64_t kHalfTexel = kSubpixel / 2;
constexpr std::size_t kOverlapExamples = 5;

/// One fan triangle of a face: indices into faceVertices / faceUvs of its three corners.
struct FanTriangle {
  int face;
  int corner[3];
};

std::vector<FanTriangle> fanTriangles(const Mesh& mesh) {
  std::vector<FanTriangle> fans;
  const int faces = mesh.faceStart.empty() ? 0 : static_cast<int>(mesh.faceStart.size()) - 1;
  for (int f = 0; f < faces; ++f) {
    const int begin = mesh.faceStart[f];
    const int end = mesh.faceStart[f + 1];
    for (int i = begin + 1; i + 1 < end; ++i) {
      fans.push_back({f, {begin, i, i + 1}});
    }
  }
  return fans;
}

/// Refuses what a UV layout cannot rasterise, naming the face (1-based, f-line order).
void checkUvs(const Mesh& mesh, const std::string& meshName) {
  if (!mesh.hasUvs() || mesh.uvs.empty()) {
    DS_THROW(kInput, meshName,
             ": the mesh has no UVs (no `vt` lines or faces without v/vt indices); a position "
             "map needs a UV layout: export the mesh with UVs");
  }
  if (mesh.faceUvs.size() != mesh.faceVertices.size()) {
    DS_THROW(kInput, meshName, ": ", mesh.faceUvs.size(), " face UV indices for ",
             mesh.faceVertices.size(), " face corners; the mesh is malformed");
  }
  const int faces = mesh.faceStart.empty() ? 0 : static_cast<int>(mesh.faceStart.size()) - 1;
  for (int f = 0; f < faces; ++f) {
    for (int c = mesh.faceStart[f]; c < mesh.faceStart[f + 1]; ++c) {
      const int uv = mesh.faceUvs[static_cast<std::size_t>(c)];
      const int corner = c - mesh.faceStart[f] + 1;
      if (uv < 0) {
        DS_THROW(kInput, meshName, ": face ", f + 1, " (f line ", f + 1, "), corner ", corner,
                 " has no UV; every face needs v/vt indices for a position map");
      }
      if (static_cast<std::size_t>(uv) >= mesh.uvs.size()) {
        DS_THROW(kInput, meshName, ": face ", f + 1, ", corner ", corner, " uses UV ", uv + 1,
                 " but the mesh has ", mesh.uvs.size(), " UVs");
      }
      const Eigen::Vector2f& value = mesh.uvs[static_cast<std::size_t>(uv)];
      const bool inside = value.x() >= 0.0f && value.x() <= 1.0f && value.y() >= 0.0f &&
                          value.y() <= 1.0f;  // false for NaN too
      if (!inside) {
        DS_THROW(kInput, meshName, ": face ", f + 1, " (f line ", f + 1, "), corner ", corner,
                 " uses vt ", uv + 1, " = (", value.x(), ", ", value.y(),
                 "), outside [0, 1]; position maps cover the 0-1 UV square only (UVs outside "
                 "it, e.g. UDIM tiles, are refused rather than wrapped or clamped): move the "
                 "UV islands into the unit square");
      }
    }
  }
}

/// floor(a / b) and ceil(a / b) for b > 0 and any sign of a.
std::int64_t floorDiv(std::int64_t a, std::int64_t b) {
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}
std::int64_t ceilDiv(std::int64_t a, std::int64_t b) {
  return -floorDiv(-a, b);
}

/// Tie rule for a texel centre exactly on edge a->b (direction dx, dy) of a triangle oriented
/// so that its interior is on the positive side: the centre belongs to the triangle iff it
/// would be inside after a tiny move by (1, epsilon). Of the two triangles sharing an edge
/// (which see it in opposite directions) exactly one passes, and at a shared vertex exactly one
/// triangle of a closed fan does, as if every centre were moved off all edges the same way.
bool ownsTie(std::int64_t dx, std::int64_t dy) {
  return dy < 0 || (dy == 0 && dx > 0);
}

/// A UV triangle in pixel space (x = u W, y = (1 - v) H): exact doubles for the weights,
/// snapped integers for coverage.
struct PixelTriangle {
  double x[3];
  double y[3];
  std::int64_t sx[3];
  std::int64_t sy[3];
};

PixelTriangle pixelTriangle(const Mesh& mesh, const FanTriangle& fan, int width, int height) {
  PixelTriangle tri{};
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector2f& uv =
        mesh.uvs[static_cast<std::size_t>(mesh.faceUvs[static_cast<std::size_t>(fan.corner[k])])];
    tri.x[k] = static_cast<double>(uv.x()) * width;
    tri.y[k] = (1.0 - static_cast<double>(uv.y())) * height;
    tri.sx[k] = std::llround(tri.x[k] * static_cast<double>(kSubpixel));
    tri.sy[k] = std::llround(tri.y[k] * static_cast<double>(kSubpixel));
  }
  return tri;
}

/// Barycentric weights (b1, b2) of the texel centre (x + 0.5, y + 0.5) in `tri`, in double
/// from the unsnapped UVs (the snapped ones only when those are degenerate in double).
void centreWeights(const PixelTriangle& tri, int x, int y, float& b1, float& b2) {
  const double cx = x + 0.5;
  const double cy = y + 0.5;
  double d =
      (tri.x[1] - tri.x[0]) * (tri.y[2] - tri.y[0]) - (tri.x[2] - tri.x[0]) * (tri.y[1] - tri.y[0]);
  if (d != 0.0) {
    b1 = static_cast<float>(
        ((cx - tri.x[0]) * (tri.y[2] - tri.y[0]) - (tri.x[2] - tri.x[0]) * (cy - tri.y[0])) / d);
    b2 = static_cast<float>(
        ((tri.x[1] - tri.x[0]) * (cy - tri.y[0]) - (cx - tri.x[0]) * (tri.y[1] - tri.y[0])) / d);
    return;
  }
  double sx[3];
  double sy[3];
  for (int k = 0; k < 3; ++k) {
    sx[k] = static_cast<double>(tri.sx[k]) / static_cast<double>(kSubpixel);
    sy[k] = static_cast<double>(tri.sy[k]) / static_cast<double>(kSubpixel);
  }
  d = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
  b1 = static_cast<float>(((cx - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (cy - sy[0])) / d);
  b2 = static_cast<float>(((sx[1] - sx[0]) * (cy - sy[0]) - (cx - sx[0]) * (sy[1] - sy[0])) / d);
}

/// Rows [firstRow, firstRow + rows) of a map: the band a raster holds (owner, distances) and,
/// within it, the rows it reports (entries, overlaps).
struct RowWindow {
  int firstRow = 0;
  int rows = 0;
  int firstCounted = 0;  ///< first row whose overlaps are counted (the band proper)
  int countedRows = 0;
};

/// Marks the texels of `window` whose centres `tri` covers (`owner` holds the window's rows);
/// texels already owned by a lower triangle are reported as overlaps, in the counted rows only,
/// and kept by their owner.
void rasterise(const PixelTriangle& tri, int t, int width, const RowWindow& window,
               const std::vector<int>& triangleFaces, std::vector<int>& owner,
               std::vector<bool>& overlapped, std::unordered_set<std::uint64_t>& pairs,
               UvOverlapReport& overlaps) {
  std::int64_t ax = tri.sx[0], ay = tri.sy[0];
  std::int64_t bx = tri.sx[1], by = tri.sy[1];
  std::int64_t cx = tri.sx[2], cy = tri.sy[2];
  const std::int64_t area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
  if (area == 0) {
    return;  // degenerate in UV: covers no texel centre
  }
  if (area < 0) {
    std::swap(bx, cx);
    std::swap(by, cy);
  }
  const std::int64_t px[3] = {ax, bx, cx};
  const std::int64_t py[3] = {ay, by, cy};
  const std::int64_t minX = std::min({ax, bx, cx});
  const std::int64_t maxX = std::max({ax, bx, cx});
  const std::int64_t minY = std::min({ay, by, cy});
  const std::int64_t maxY = std::max({ay, by, cy});
  // Texel x has its centre at x * S + S/2.
  const std::int64_t x0 = std::max<std::int64_t>(0, ceilDiv(minX - kHalfTexel, kSubpixel));
  const std::int64_t x1 = std::min<std::int64_t>(width - 1, floorDiv(maxX - kHalfTexel, kSubpixel));
  const std::int64_t y0 =
      std::max<std::int64_t>(window.firstRow, ceilDiv(minY - kHalfTexel, kSubpixel));
  const std::int64_t y1 = std::min<std::int64_t>(window.firstRow + window.rows - 1,
                                                 floorDiv(maxY - kHalfTexel, kSubpixel));
  for (std::int64_t y = y0; y <= y1; ++y) {
    const std::int64_t sy = y * kSubpixel + kHalfTexel;
    const bool counted = y >= window.firstCounted && y < window.firstCounted + window.countedRows;
    for (std::int64_t x = x0; x <= x1; ++x) {
      const std::int64_t sx = x * kSubpixel + kHalfTexel;
      bool inside = true;
      for (int e = 0; e < 3 && inside; ++e) {
        const int a = e;
        const int b = (e + 1) % 3;
        const std::int64_t dx = px[b] - px[a];
        const std::int64_t dy = py[b] - py[a];
        const std::int64_t edge = dx * (sy - py[a]) - dy * (sx - px[a]);
        inside = edge > 0 || (edge == 0 && ownsTie(dx, dy));
      }
      if (!inside) {
        continue;
      }
      const std::size_t texel = static_cast<std::size_t>((y - window.firstRow) * width + x);
      if (owner[texel] < 0) {
        owner[texel] = t;
        continue;
      }
      if (!counted) {
        continue;
      }
      if (!overlapped[texel]) {
        overlapped[texel] = true;
        ++overlaps.texels;
      }
      const int kept = triangleFaces[static_cast<std::size_t>(owner[texel])];
      const int hidden = triangleFaces[static_cast<std::size_t>(t)];
      const std::uint64_t key =
          (static_cast<std::uint64_t>(static_cast<std::uint32_t>(kept)) << 32) |
          static_cast<std::uint32_t>(hidden);
      if (pairs.insert(key).second) {
        ++overlaps.facePairs;
        if (overlaps.examples.size() < kOverlapExamples) {
          overlaps.examples.emplace_back(kept, hidden);
        }
      }
    }
  }
}

/// Chessboard distance (max(|dx|, |dy|)) of every texel to the nearest covered one, capped at
/// `cap`: the two-pass 8-neighbour chamfer transform, exact for this metric.
std::vector<std::uint16_t> chessboardDistance(const std::vector<int>& owner, int width, int height,
                                              int cap) {
  std::vector<std::uint16_t> dist(owner.size());
  for (std::size_t i = 0; i < owner.size(); ++i) {
    dist[i] = static_cast<std::uint16_t>(owner[i] >= 0 ? 0 : cap);
  }
  const auto at = [&](int x, int y) -> std::uint16_t& {
    return dist[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                static_cast<std::size_t>(x)];
  };
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      int d = at(x, y);
      if (x > 0) {
        d = std::min(d, at(x - 1, y) + 1);
      }
      if (y > 0) {
        for (int nx = std::max(0, x - 1); nx <= std::min(width - 1, x + 1); ++nx) {
          d = std::min(d, at(nx, y - 1) + 1);
        }
      }
      at(x, y) = static_cast<std::uint16_t>(std::min(d, cap));
    }
  }
  for (int y = height - 1; y >= 0; --y) {
    for (int x = width - 1; x >= 0; --x) {
      int d = at(x, y);
      if (x + 1 < width) {
        d = std::min(d, at(x + 1, y) + 1);
      }
      if (y + 1 < height) {
        for (int nx = std::max(0, x - 1); nx <= std::min(width - 1, x + 1); ++nx) {
          d = std::min(d, at(nx, y + 1) + 1);
        }
      }
      at(x, y) = static_cast<std::uint16_t>(std::min(d, cap));
    }
  }
  return dist;
}

/// The covered texel a padded texel at chessboard distance `ring` copies: on that ring, the
/// smallest Euclidean distance, then the lowest row-major index.
std::size_t padSource(const std::vector<int>& owner, int width, int height, int x, int y,
                      int ring) {
  std::size_t best = std::numeric_limits<std::size_t>::max();
  long long bestDistance = std::numeric_limits<long long>::max();
  const auto consider = [&](int nx, int ny) {
    if (nx < 0 || ny < 0 || nx >= width || ny >= height) {
      return;
    }
    const std::size_t texel = static_cast<std::size_t>(ny) * static_cast<std::size_t>(width) +
                              static_cast<std::size_t>(nx);
    if (owner[texel] < 0) {
      return;
    }
    const long long dx = nx - x;
    const long long dy = ny - y;
    const long long distance = dx * dx + dy * dy;
    if (distance < bestDistance || (distance == bestDistance && texel < best)) {
      bestDistance = distance;
      best = texel;
    }
  };
  for (int dx = -ring; dx <= ring; ++dx) {
    consider(x + dx, y - ring);
    consider(x + dx, y + ring);
  }
  for (int dy = -ring + 1; dy <= ring - 1; ++dy) {
    consider(x - ring, y + dy);
    consider(x + ring, y + dy);
  }
  return best;
}

void checkMapSize(int width, int height, int padding) {
  if (width < 1 || height < 1 || width > kMaxPositionMapSide || height > kMaxPositionMapSide) {
    DS_THROW(kUsage, "position map size ", width, "x", height, " is outside 1..",
             kMaxPositionMapSide, " texels per side (--res)");
  }
  if (padding < 0 || padding > kMaxPositionMapPadding) {
    DS_THROW(kUsage, "position map padding ", padding, " is outside 0..", kMaxPositionMapPadding,
             " texels (--padding)");
  }
}

/// The triangle tables of `tables` (triangles, their faces, the incident triangles of each
/// vertex) from the fan triangles of `mesh`.
void fillTriangleTables(const Mesh& mesh, const std::vector<FanTriangle>& fans,
                        PositionMapTables& tables) {
  const std::size_t triangleCount = fans.size();
  tables.triangles.resize(3 * triangleCount);
  tables.triangleFaces.resize(triangleCount);
  for (std::size_t t = 0; t < triangleCount; ++t) {
    for (int k = 0; k < 3; ++k) {
      tables.triangles[3 * t + static_cast<std::size_t>(k)] =
          mesh.faceVertices[static_cast<std::size_t>(fans[t].corner[k])];
    }
    tables.triangleFaces[t] = fans[t].face;
  }
  // Incident triangles per vertex (CSR, ascending triangle ids): the normals kernel gathers
  // over them instead of scattering with atomics.
  const std::size_t vertices = static_cast<std::size_t>(tables.vertexCount);
  tables.vertexTriangleStart.assign(vertices + 1, 0);
  for (int v : tables.triangles) {
    ++tables.vertexTriangleStart[static_cast<std::size_t>(v) + 1];
  }
  for (std::size_t v = 0; v < vertices; ++v) {
    tables.vertexTriangleStart[v + 1] += tables.vertexTriangleStart[v];
  }
  tables.vertexTriangles.resize(tables.triangles.size());
  std::vector<int> next(tables.vertexTriangleStart.begin(), tables.vertexTriangleStart.end() - 1);
  for (std::size_t t = 0; t < triangleCount; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int v = tables.triangles[3 * t + static_cast<std::size_t>(k)];
      tables.vertexTriangles[static_cast<std::size_t>(next[static_cast<std::size_t>(v)]++)] =
          static_cast<int>(t);
    }
  }
}

/// What a raster keeps between bands: the map's size, its triangles in pixel space and the
/// tables every band shares (sizes, triangles, no texel).
struct RasterLayout {
  PositionMapTables shared;
  std::vector<PixelTriangle> pixels;
  std::vector<int> firstRows;  ///< per triangle: the first texel row its box reaches
  std::vector<int> lastRows;   ///< and the last
};

/// The owner triangle of every texel of `window` (lowest index first); overlaps in its counted
/// rows go to `pairs` and `overlaps`.
std::vector<int> windowOwners(const RasterLayout& layout, const RowWindow& window,
                              std::unordered_set<std::uint64_t>& pairs, UvOverlapReport& overlaps) {
  const PositionMapTables& shared = layout.shared;
  const std::size_t texels =
      static_cast<std::size_t>(shared.width) * static_cast<std::size_t>(window.rows);
  std::vector<int> owner(texels, -1);
  std::vector<bool> overlapped(texels, false);
  const int lastRow = window.firstRow + window.rows - 1;
  for (std::size_t t = 0; t < layout.pixels.size(); ++t) {
    if (layout.lastRows[t] >= window.firstRow && layout.firstRows[t] <= lastRow) {
      rasterise(layout.pixels[t], static_cast<int>(t), shared.width, window, shared.triangleFaces,
                owner, overlapped, pairs, overlaps);
    }
  }
  return owner;
}

/// The entries of the band rows of `window` (the rows it counts) into `band`: every covered
/// texel and, with padding, every texel within `padding` of one (copying its nearest covered
/// texel's triangle and weights), in row-major order, and the band's coverage plane.
void fillBandEntries(const RasterLayout& layout, const RowWindow& window,
                     const std::vector<int>& owner, PositionMapTables& band) {
  const int width = band.width;
  const int padding = band.padding;
  const std::vector<std::uint16_t> dist =
      padding > 0 ? chessboardDistance(owner, width, window.rows, padding + 1)
                  : std::vector<std::uint16_t>{};
  const std::size_t rowTexels = static_cast<std::size_t>(width);
  const std::size_t skipped =
      static_cast<std::size_t>(window.firstCounted - window.firstRow) * rowTexels;
  const std::size_t bandTexels = static_cast<std::size_t>(window.countedRows) * rowTexels;
  // Band texel -> its entry, so that padded texels can name their source's (-1 outside).
  std::vector<int> entryOf(bandTexels, -1);
  std::size_t active = 0;
  for (std::size_t texel = 0; texel < bandTexels; ++texel) {
    const std::size_t at = skipped + texel;
    if (owner[at] >= 0 || (padding > 0 && dist[at] <= padding)) {
      entryOf[texel] = static_cast<int>(active++);
    }
  }
  band.texels.resize(active);
  for (std::size_t texel = 0; texel < bandTexels; ++texel) {
    if (entryOf[texel] >= 0) {
      band.texels[static_cast<std::size_t>(entryOf[texel])] = static_cast<int>(texel);
    }
  }
  band.texelTriangles.resize(active);
  band.texelWeights.resize(2 * active);
  band.texelSources.resize(active);
  band.coverage.assign(bandTexels, 0.0f);
  for (std::size_t e = 0; e < active; ++e) {
    const std::size_t texel = static_cast<std::size_t>(band.texels[e]);
    const int x = static_cast<int>(texel % rowTexels);
    const int y = static_cast<int>(texel / rowTexels) + window.firstCounted - window.firstRow;
    std::size_t source = skipped + texel;  // in the window
    if (owner[source] >= 0) {
      band.coverage[texel] = 1.0f;
      ++band.coveredCount;
    } else {
      source = padSource(owner, width, window.rows, x, y, dist[skipped + texel]);
      ++band.paddedCount;
    }
    const int sx = static_cast<int>(source % rowTexels);
    const int sy = static_cast<int>(source / rowTexels);
    band.texelTriangles[e] = owner[source];
    // Window row sy is map row firstRow + sy: the centre's weights in the whole map's pixels.
    centreWeights(layout.pixels[static_cast<std::size_t>(owner[source])], sx, sy + window.firstRow,
                  band.texelWeights[2 * e], band.texelWeights[2 * e + 1]);
    const bool inBand = source >= skipped && source < skipped + bandTexels;
    band.texelSources[e] = inBand ? entryOf[source - skipped] : -1;
  }
}

/// Adds the covered and padded texels of the band rows of `window` to the counts of `tables`
/// (fillBandEntries' counts, without its entries).
void countBand(const RowWindow& window, const std::vector<int>& owner, PositionMapTables& tables) {
  const int padding = tables.padding;
  const std::vector<std::uint16_t> dist =
      padding > 0 ? chessboardDistance(owner, tables.width, window.rows, padding + 1)
                  : std::vector<std::uint16_t>{};
  const std::size_t rowTexels = static_cast<std::size_t>(tables.width);
  const std::size_t first =
      static_cast<std::size_t>(window.firstCounted - window.firstRow) * rowTexels;
  const std::size_t last = first + static_cast<std::size_t>(window.countedRows) * rowTexels;
  for (std::size_t texel = first; texel < last; ++texel) {
    if (owner[texel] >= 0) {
      ++tables.coveredCount;
    } else if (padding > 0 && dist[texel] <= padding) {
      ++tables.paddedCount;
    }
  }
}

/// The window a band of `rows` rows from `firstRow` needs: padding rows on each side (a padded
/// texel copies a covered texel up to `padding` rows away, and its distance is decided by
/// those rows alone), within the map.
RowWindow bandWindow(const PositionMapTables& shared, int firstRow, int rows) {
  RowWindow window;
  window.firstRow = std::max(0, firstRow - shared.padding);
  window.rows = std::min(shared.height, firstRow + rows + shared.padding) - window.firstRow;
  window.firstCounted = firstRow;
  window.countedRows = rows;
  return window;
}

}  // namespace uv_raster_parts
using namespace uv_raster_parts;

struct PositionMapRaster::Layout : RasterLayout {};

PositionMapRaster::PositionMapRaster(const Mesh& mesh, int width, int height, int padding,
                                     const std::string& meshName)
    : mLayout(std::make_unique<Layout>()) {
  checkMapSize(width, height, padding);
  if (mesh.vertexCount() <= 0 || mesh.faceStart.size() < 2) {
    DS_THROW(kInput, meshName, ": the mesh has no faces; a position map needs UV triangles");
  }
  checkUvs(mesh, meshName);
  PositionMapTables& shared = mLayout->shared;
  shared.width = width;
  shared.height = height;
  shared.padding = padding;
  shared.vertexCount = mesh.vertexCount();
  shared.topologyHash = topologyHash(mesh);
  const std::vector<FanTriangle> fans = fanTriangles(mesh);
  fillTriangleTables(mesh, fans, shared);
  for (const FanTriangle& fan : fans) {
    const PixelTriangle tri = pixelTriangle(mesh, fan, width, height);
    const std::int64_t minY = std::min({tri.sy[0], tri.sy[1], tri.sy[2]});
    const std::int64_t maxY = std::max({tri.sy[0], tri.sy[1], tri.sy[2]});
    mLayout->pixels.push_back(tri);
    // Rows whose centres the box can reach (clamped to the map; empty when first > last).
    mLayout->firstRows.push_back(static_cast<int>(
        std::clamp<std::int64_t>(ceilDiv(minY - kHalfTexel, kSubpixel), 0, height)));
    mLayout->lastRows.push_back(static_cast<int>(
        std::clamp<std::int64_t>(floorDiv(maxY - kHalfTexel, kSubpixel), -1, height - 1)));
  }
}

PositionMapRaster::~PositionMapRaster() = default;

const PositionMapTables& PositionMapRaster::shared() const {
  return mLayout->shared;
}

PositionMapTables PositionMapRaster::band(int firstRow, int rows) const {
  const PositionMapTables& shared = mLayout->shared;
  if (firstRow < 0 || rows < 1 || firstRow + rows > shared.height) {
    DS_THROW(kInternal, "position map band of rows ", firstRow, "-", firstRow + rows - 1,
             " is outside the map's ", shared.height, " rows");
  }
  PositionMapTables band = shared;
  band.height = rows;
  const RowWindow window = bandWindow(shared, firstRow, rows);
  std::unordered_set<std::uint64_t> pairs;
  const std::vector<int> owner = windowOwners(*mLayout, window, pairs, band.overlaps);
  fillBandEntries(*mLayout, window, owner, band);
  return band;
}

PositionMapTables PositionMapRaster::survey(int bandRows) const {
  const PositionMapTables& shared = mLayout->shared;
  PositionMapTables whole = shared;
  std::unordered_set<std::uint64_t> pairs;  // each overlapping face pair once, across bands
  const int step = std::max(1, bandRows);
  for (int firstRow = 0; firstRow < shared.height; firstRow += step) {
    const int rows = std::min(step, shared.height - firstRow);
    const RowWindow window = bandWindow(shared, firstRow, rows);
    const std::vector<int> owner = windowOwners(*mLayout, window, pairs, whole.overlaps);
    countBand(window, owner, whole);
  }
  return whole;
}

PositionMapTables buildPositionMapTables(const Mesh& mesh, int width, int height, int padding,
                                         const std::string& meshName) {
  return PositionMapRaster(mesh, width, height, padding, meshName).band(0, height);
}

}  // namespace drivenshape
