// SPDX-License-Identifier: Apache-2.0
// The strain limit's tables and the checks both backends share (strain_limit.h).

#include "strain_limit.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/mesh.h>

namespace drivenshape {
namespace {

double restLength(const Mesh& mesh, int a, int b) {
  const double dx = double(mesh.positions(b, 0)) - mesh.positions(a, 0);
  const double dy = double(mesh.positions(b, 1)) - mesh.positions(a, 1);
  const double dz = double(mesh.positions(b, 2)) - mesh.positions(a, 2);
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

/// Vertex `vertex`'s share of the correction of its edge to `other`: w_v / (w_v + w_o), 0 when
/// the vertex is fixed (or both are).
float shareOf(const std::vector<float>& weights, int vertex, int other) {
  const double own = weights.empty() ? 1.0 : weights[static_cast<std::size_t>(vertex)];
  const double theirs = weights.empty() ? 1.0 : weights[static_cast<std::size_t>(other)];
  return own > 0.0 ? static_cast<float>(own / (own + theirs)) : 0.0f;
}

}  // namespace

std::vector<float> chebyshevWeights(int iterations, double rho, int from) {
  if (iterations < 0 || !(rho >= 0.0 && rho < 1.0) || from < 1) {
    DS_THROW(kInternal, "chebyshevWeights: iterations ", iterations, " (>= 0), rho ", rho,
             " (0 to below 1), from ", from, " (>= 1)");
  }
  std::vector<float> omega(static_cast<std::size_t>(iterations), 1.0f);
  const double rho2 = rho * rho;
  double w = 1.0;
  for (int k = from; k < iterations && rho > 0.0; ++k) {
    w = k == from ? 2.0 / (2.0 - rho2) : 4.0 / (4.0 - rho2 * w);
    omega[static_cast<std::size_t>(k)] = static_cast<float>(w);
  }
  return omega;
}

StrainLimitTables strainLimitTables(const Mesh& mesh, double band, int iterations,
                                    double relaxation, std::vector<float> omega,
                                    const std::vector<float>& weights, double compression) {
  const int vertexCount = mesh.vertexCount();
  if (!(band >= 0.0 && band < 1.0) || iterations < 0 || !(relaxation > 0.0 && relaxation < 2.0) ||
      !(compression > 0.0 && compression <= 1.0)) {
    DS_THROW(kInternal, "strainLimitTables: band ", band, " (0 to below 1), iterations ",
             iterations, " (>= 0), relaxation ", relaxation, " (between 0 and 2), compression ",
             compression, " (above 0, at most 1)");
  }
  if (!weights.empty() && weights.size() != static_cast<std::size_t>(vertexCount)) {
    DS_THROW(kInternal, "strainLimitTables: ", weights.size(), " weights for ", vertexCount,
             " vertices");
  }
  for (const float w : weights) {
    if (!(w >= 0.0f) || !std::isfinite(w)) {
      DS_THROW(kInternal, "strainLimitTables: a vertex weight of ", w, " (>= 0 and finite)");
    }
  }
  if (omega.empty()) {
    omega.assign(static_cast<std::size_t>(iterations), 1.0f);
  }
  if (omega.size() != static_cast<std::size_t>(iterations)) {
    DS_THROW(kInternal, "strainLimitTables: ", omega.size(), " Chebyshev weights for ", iterations,
             " iterations");
  }
  // The band at float precision: the Blender add-on's properties are float32, so its 0.01 is
  // 0.0099999998; taken that way here, every tool's 0.01 gives the same tables, bit for bit.
  const double bandAsFloat = static_cast<float>(band);
  StrainLimitTables tables;
  tables.vertexCount = vertexCount;
  tables.iterations = iterations;
  tables.omega = std::move(omega);
  tables.compression = static_cast<float>(compression);
  // Two passes over the edges (sorted, each once): count each vertex's entries, then fill them,
  // so every vertex lists its edges in meshEdges() order.
  std::vector<MeshEdge> edges;
  std::vector<double> lengths;
  for (const MeshEdge& edge : meshEdges(mesh)) {
    const double length = restLength(mesh, edge[0], edge[1]);
    if (length > 0.0) {
      edges.push_back(edge);
      lengths.push_back(length);
    }
  }
  tables.start.assign(static_cast<std::size_t>(vertexCount) + 1, 0);
  for (const MeshEdge& edge : edges) {
    ++tables.start[static_cast<std::size_t>(edge[0]) + 1];
    ++tables.start[static_cast<std::size_t>(edge[1]) + 1];
  }
  for (std::size_t v = 0; v < static_cast<std::size_t>(vertexCount); ++v) {
    tables.start[v + 1] += tables.start[v];
  }
  const std::size_t entries = 2 * edges.size();
  tables.other.resize(entries);
  tables.lower.resize(entries);
  tables.upper.resize(entries);
  tables.share.resize(entries);
  std::vector<std::int32_t> next(tables.start.begin(), tables.start.end() - 1);
  for (std::size_t e = 0; e < edges.size(); ++e) {
    for (int side = 0; side < 2; ++side) {
      const int vertex = edges[e][static_cast<std::size_t>(side)];
      const int other = edges[e][static_cast<std::size_t>(1 - side)];
      const std::size_t at = static_cast<std::size_t>(next[static_cast<std::size_t>(vertex)]++);
      tables.other[at] = other;
      tables.lower[at] = static_cast<float>((1.0 - bandAsFloat) * lengths[e]);
      tables.upper[at] = static_cast<float>((1.0 + bandAsFloat) * lengths[e]);
      tables.share[at] = shareOf(weights, vertex, other);
    }
  }
  tables.step.resize(static_cast<std::size_t>(vertexCount));
  for (std::size_t v = 0; v < tables.step.size(); ++v) {
    int moving = 0;
    for (std::int32_t k = tables.start[v]; k < tables.start[v + 1]; ++k) {
      moving += tables.share[static_cast<std::size_t>(k)] > 0.0f ? 1 : 0;
    }
    tables.step[v] = moving > 0 ? static_cast<float>(relaxation / moving) : 0.0f;
  }
  return tables;
}

namespace strain_limit_checks {

void checkTables(const StrainLimitTables& t) {
  const std::size_t entries = t.other.size();
  const std::size_t vertices = static_cast<std::size_t>(std::max(t.vertexCount, 0));
  bool ok = t.vertexCount > 0 && t.iterations >= 0 && t.start.size() == vertices + 1 &&
            t.step.size() == vertices && t.lower.size() == entries && t.upper.size() == entries &&
            t.share.size() == entries && t.start.front() == 0 &&
            static_cast<std::size_t>(t.start.back()) == entries &&
            t.omega.size() == static_cast<std::size_t>(std::max(t.iterations, 0)) &&
            (t.omega.empty() || t.omega.front() == 1.0f) && t.compression > 0.0f &&
            t.compression <= 1.0f;
  for (std::size_t k = 0; ok && k < t.omega.size(); ++k) {
    ok = t.omega[k] >= 1.0f && t.omega[k] < 2.0f;
  }
  for (std::size_t v = 0; ok && v < vertices; ++v) {
    ok = t.start[v] <= t.start[v + 1] && t.step[v] >= 0.0f && t.step[v] < 2.0f;
  }
  for (std::size_t i = 0; ok && i < entries; ++i) {
    ok = t.other[i] >= 0 && t.other[i] < t.vertexCount && t.lower[i] >= 0.0f &&
         t.lower[i] <= t.upper[i] && t.share[i] >= 0.0f && t.share[i] <= 1.0f;
  }
  if (!ok) {
    DS_THROW(kInternal, "StrainLimitBackend::upload: inconsistent tables (", t.vertexCount,
             " vertices, ", t.start.size(), " offsets, ", t.step.size(), " steps, ", entries,
             " entries, ", t.iterations, " iterations)");
  }
}

void checkInFront(int frameCount, int vertexCount) {
  if (frameCount < 0 || vertexCount < 0) {
    DS_THROW(kInternal, "StrainLimitBackend::keepInFront called with ", frameCount, " frames of ",
             vertexCount, " vertices");
  }
}

void checkCall(bool uploaded, int frameCount) {
  if (!uploaded) {
    DS_THROW(kInternal, "StrainLimitBackend::limit called before upload()");
  }
  if (frameCount < 0) {
    DS_THROW(kInternal, "StrainLimitBackend::limit called with ", frameCount, " frames");
  }
}

}  // namespace strain_limit_checks

}  // namespace drivenshape
