// SPDX-License-Identifier: Apache-2.0
// The host reference of kernels/strain_limit.cl (strain_limit.h): the same iterations in
// double, each frame kept in double between iterations and rounded to float once at the end;
// frames in parallel on host threads (each frame alone, so the thread count changes nothing).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "parallel.h"

#include "strain_limit.h"

namespace drivenshape {
namespace {

class HostStrainLimit final : public StrainLimitBackend {
 public:
  explicit HostStrainLimit(int threads) : mThreads(threads) {}

  std::string name() const override { return "host"; }

  void upload(const StrainLimitTables& tables) override {
    strain_limit_checks::checkTables(tables);
    mTables = tables;
    mUploaded = true;
  }

  void limit(int frameCount, float* positions, const float* planes, std::int32_t* stayed,
             float reach) override {
    strain_limit_checks::checkCall(mUploaded, frameCount);
    if (mTables.iterations == 0) {
      return;
    }
    const std::size_t values = 3 * static_cast<std::size_t>(mTables.vertexCount);
    parallelFor(frameCount, mThreads, [&](int f) {
      float* frame = positions + static_cast<std::size_t>(f) * values;
      std::vector<double> now(frame, frame + values);
      std::vector<double> next(values);  // x_{k-1} before iteration k, then x_{k+1}
      const float* framePlanes =
          planes != nullptr ? planes + static_cast<std::size_t>(f) * 4 * mTables.vertexCount
                            : nullptr;
      for (int i = 0; i < mTables.iterations; ++i) {
        iterate(now.data(), next.data(), mTables.omega[static_cast<std::size_t>(i)], framePlanes);
        std::swap(now, next);
      }
      std::int32_t* frameStayed =
          stayed != nullptr ? stayed + static_cast<std::size_t>(f) * mTables.vertexCount : nullptr;
      for (std::size_t v = 0; v < values / 3; ++v) {
        float* x = frame + 3 * v;
        const float end[3] = {static_cast<float>(now[3 * v]), static_cast<float>(now[3 * v + 1]),
                              static_cast<float>(now[3 * v + 2])};
        if (frameStayed != nullptr && frameStayed[v] != 0) {
          frameStayed[v] = travel(x, end) < static_cast<double>(reach) ? 1 : 0;
        }
        std::copy(end, end + 3, x);
      }
    });
  }

  void keepInFront(int frameCount, int vertexCount, float* positions,
                   const float* planes) override {
    strain_limit_checks::checkInFront(frameCount, vertexCount);
    const std::size_t count = static_cast<std::size_t>(vertexCount);
    parallelFor(frameCount, mThreads, [&](int f) {
      const std::size_t first = static_cast<std::size_t>(f) * count;
      for (std::size_t v = first; v < first + count; ++v) {
        float* x = positions + 3 * v;
        double at[3] = {x[0], x[1], x[2]};
        inFront(planes + 4 * v, at);
        for (int a = 0; a < 3; ++a) {
          x[a] = static_cast<float>(at[a]);
        }
      }
    });
  }

 private:
  /// One iteration of one frame: every vertex of `in` (3V values, x_k) into `out`, which holds
  /// x_{k-1} where `omega` is not 1 (StrainLimitTables), kept in front of its plane (4V values,
  /// or null).
  void iterate(const double* in, double* out, double omega, const float* planes) const {
    const StrainLimitTables& t = mTables;
    for (std::size_t v = 0; v < static_cast<std::size_t>(t.vertexCount); ++v) {
      const double* p = in + 3 * v;
      double sum[3] = {0.0, 0.0, 0.0};
      bool moves = false;
      for (std::int32_t k = t.start[v]; k < t.start[v + 1]; ++k) {
        const std::size_t entry = static_cast<std::size_t>(k);
        const double share = t.share[entry];
        if (share == 0.0) {
          continue;
        }
        const double* q = in + 3 * static_cast<std::size_t>(t.other[entry]);
        const double d[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
        const double length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        double target = 0.0;
        double gain = 1.0;
        if (length > t.upper[entry]) {
          target = t.upper[entry];
        } else if (length < t.lower[entry] && length > 0.0) {
          target = t.lower[entry];
          gain = t.compression;
        } else {
          continue;
        }
        const double scale = gain * share * (length - target) / length;
        for (int a = 0; a < 3; ++a) {
          sum[a] += scale * d[a];
        }
        moves = true;
      }
      double* o = out + 3 * v;
      const double step = t.step[v];
      // A vertex no edge can move (step 0) takes no momentum: only its plane moves it.
      const bool accelerated = omega != 1.0 && step != 0.0;
      for (int a = 0; a < 3; ++a) {
        const double jacobi = moves ? p[a] + step * sum[a] : p[a];
        o[a] = accelerated ? omega * (jacobi - o[a]) + o[a] : jacobi;
      }
      if (planes != nullptr) {
        inFront(planes + 4 * v, o);
      }
    }
  }

  /// |end - start| of one vertex, in double.
  static double travel(const float* start, const float* end) {
    double sum = 0.0;
    for (int a = 0; a < 3; ++a) {
      const double d = static_cast<double>(end[a]) - start[a];
      sum += d * d;
    }
    return std::sqrt(sum);
  }

  /// Moves x onto the plane (m, c) when it lies behind it (m . x < c); no plane when m is 0.
  static void inFront(const float* plane, double* x) {
    const double below =
        static_cast<double>(plane[3]) - (plane[0] * x[0] + plane[1] * x[1] + plane[2] * x[2]);
    if (below > 0.0) {
      for (int a = 0; a < 3; ++a) {
        x[a] += below * plane[a];
      }
    }
  }

  int mThreads = 0;
  StrainLimitTables mTables;
  bool mUploaded = false;
};

}  // namespace

std::unique_ptr<StrainLimitBackend> makeHostStrainLimit(int threads) {
  return std::make_unique<HostStrainLimit>(threads);
}

}  // namespace drivenshape
