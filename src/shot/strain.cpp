// SPDX-License-Identifier: Apache-2.0
// Edge strain (drivenshape/evaluate.h): per edge, per frame, and over a shot (strain_total.h).
#include "strain_total.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include <drivenshape/error.h>

namespace drivenshape {
namespace {

double edgeLength(const float* xyz, int a, int b) {
  const double dx = double(xyz[3 * b]) - xyz[3 * a];
  const double dy = double(xyz[3 * b + 1]) - xyz[3 * a + 1];
  const double dz = double(xyz[3 * b + 2]) - xyz[3 * a + 2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

}  // namespace

long long strainPercentileRank(long long n) {
  return (95 * n + 99) / 100;
}

std::vector<double> edgeStrains(const float* rest, const float* positions, int vertexCount,
                                const std::vector<MeshEdge>& edges) {
  std::vector<double> strains(edges.size());
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const int a = edges[e][0];
    const int b = edges[e][1];
    if (a < 0 || b < 0 || a >= vertexCount || b >= vertexCount) {
      DS_THROW(kInput, "edge ", e, " (", a, ", ", b, ") names a vertex outside the ", vertexCount,
               " vertices");
    }
    const double restLength = edgeLength(rest, a, b);
    if (!(restLength > 0.0)) {
      DS_THROW(kInput, "edge ", e, " (vertices ", a, " and ", b,
               ") has zero length at rest: it has no strain; leave it out");
    }
    strains[e] = edgeLength(positions, a, b) / restLength - 1.0;
  }
  return strains;
}

StrainFigures strainFigures(const std::vector<double>& strains) {
  StrainTotal total(static_cast<long long>(strains.size()));
  total.add(strains);
  return total.figures();
}

StrainFigures frameStrain(const float* rest, const float* positions, int vertexCount,
                          const std::vector<MeshEdge>& edges) {
  return strainFigures(edgeStrains(rest, positions, vertexCount, edges));
}

StrainTotal::StrainTotal(long long total)
    : mTotal(total), mKeep(static_cast<std::size_t>(total - strainPercentileRank(total) + 1)) {}

void StrainTotal::add(const std::vector<double>& strains) {
  for (double strain : strains) {
    const double magnitude = std::abs(strain);
    mSum += magnitude;
    mOver += magnitude > kStrainLimit ? 1 : 0;
    mLargest.push_back(magnitude);
  }
  mCount += static_cast<long long>(strains.size());
  // Amortised linear: prune only once the buffer holds twice what must be kept.
  if (mLargest.size() > 2 * mKeep + 1024) {
    keepLargest();
  }
}

void StrainTotal::keepLargest() {
  if (mLargest.size() > mKeep) {
    const auto first = mLargest.begin() + static_cast<std::ptrdiff_t>(mLargest.size() - mKeep);
    std::nth_element(mLargest.begin(), first, mLargest.end());
    mLargest.erase(mLargest.begin(), first);
  }
}

StrainFigures StrainTotal::figures() {
  if (mCount != mTotal) {
    DS_THROW(kInternal, "strain over ", mCount, " values, not the ", mTotal, " announced");
  }
  StrainFigures figures;
  figures.values = mTotal;
  if (mTotal == 0) {
    return figures;
  }
  keepLargest();
  figures.mean = mSum / double(mTotal);
  figures.overShare = double(mOver) / double(mTotal);
  // The value at rank ceil(0.95 n) is the m-th largest: the smallest of the m kept.
  figures.p95 = *std::min_element(mLargest.begin(), mLargest.end());
  return figures;
}

}  // namespace drivenshape
