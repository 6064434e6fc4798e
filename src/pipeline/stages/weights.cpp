// SPDX-License-Identifier: Apache-2.0
// The blend weights of each frame (docs/method.md, "Weights"): the DrivenShape QP per weight
// problem (min ||A w - b||, sum w = 1, 0 <= w <= 1, optionally within maxWeightChange of the
// previous frame's weights), or the nearest-shape baseline.

#include <algorithm>
#include <cmath>

#include <drivenshape/error.h>

#include "parallel.h"

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class WeightsStage final : public Stage {
 public:
  explicit WeightsStage(Model& model) : mModel(model) {
    const bool qp = model.settings.weightMode == WeightMode::kQp;
    declare(Arrays{Array::Aligned}
                .with(Array::Frames, qp)
                .with(Array::Projections, qp)
                .with(Array::Norms, qp)
                .with(Array::HostProjections, qp),
            Arrays{Array::Weights, Array::Records}.with(Array::Solutions, qp));
    if (model.settings.weightMode == WeightMode::kNearest) {
      mShapes = driverMatrix(model.driverShapes, model.k, model.vp, {});
    }
  }

  const char* name() const override { return "weights"; }

  void describe(nlohmann::json& settings) const override {
    if (!mModel.settings.regions) {
      return;
    }
    nlohmann::json regions = nlohmann::json::array();
    for (const Region& region : mModel.settings.regions->regions) {
      regions.push_back({{"name", region.name},
                         {"driver_vertices", region.driverVertices.size()},
                         {"driven_vertices", region.drivenVertices.size()}});
    }
    settings["regions"] = regions;
    settings["region_falloff"] = mModel.settings.regions->falloff;
  }

  void reset(bool /*all*/) override { mPrevious.clear(); }

  void run(Batch& batch) override {
    if (mModel.settings.weightMode == WeightMode::kQp) {
      solve(batch);
    }
    const int k = mModel.k, regionCount = mModel.regionCount();
    std::vector<float>& weights = batch.out<Array::Weights>();
    weights.assign(static_cast<std::size_t>(batch.count()) * regionCount * k, 0.0f);
    FrameRecord* records = batch.out<Array::Records>();
    const float* aligned = batch.alignedBlock(mModel.driverValues);
    parallelFor(batch.count(), mModel.threads, [&](int i) {
      FrameRecord& record = records[i];
      const float* frame = aligned + i * mModel.driverValues;
      if (mModel.settings.weightMode == WeightMode::kQp) {
        recordSolutions(batch, i, record);
        record.directResidual = directResidual(frame, record.weights);
      } else {
        nearest(frame, record);
        record.directResidual = record.relativeResidual;  // computed directly there
      }
      for (std::size_t s = 0; s < record.weights.size(); ++s) {
        weights[i * regionCount * k + s] = static_cast<float>(record.weights[s]);
      }
    });
  }

 private:
  /// The QP of every solve frame and region. With the temporal bound, frames are solved in
  /// order, each bounded by the one before it (the first by the previous call's last frame,
  /// unless the state was reset).
  void solve(Batch& batch) {
    const int n = batch.solveCount(), regionCount = mModel.regionCount();
    const bool temporal = mModel.settings.maxWeightChange > 0;
    std::vector<SimplexSolution>& solutions = batch.out<Array::Solutions>();
    solutions.assign(static_cast<std::size_t>(n) * regionCount, SimplexSolution{});
    if (temporal) {
      for (int i = 0; i < n; ++i) {
        parallelFor(regionCount, std::min(mModel.threads, regionCount),
                    [&](int r) { solveOne(batch, i, r); });
      }
      mPrevious.assign(solutions.end() - regionCount, solutions.end());
    } else {
      parallelFor(n * regionCount, mModel.threads,
                  [&](int item) { solveOne(batch, item / regionCount, item % regionCount); });
    }
  }

  void solveOne(Batch& batch, int i, int r) {
    const int k = mModel.k, regionCount = mModel.regionCount();
    const int item = i * regionCount + r;
    Eigen::VectorXd p(k - 1);
    double rr = 0, bb = 0;
    const std::vector<double>& hostProjections = batch.in<Array::HostProjections>();
    if (hostProjections.empty()) {
      const std::vector<float>& projections = batch.in<Array::Projections>();
      const std::vector<float>& norms = batch.in<Array::Norms>();
      p = Eigen::Map<const Eigen::VectorXf>(&projections[i * (k - 1)], k - 1).cast<double>();
      rr = norms[2 * i];
      bb = norms[2 * i + 1];
    } else {
      const double* in = &hostProjections[static_cast<std::size_t>(item) * (k + 1)];
      p = Eigen::Map<const Eigen::VectorXd>(in, k - 1);
      rr = in[k - 1];
      bb = in[k];
    }
    const WeightProblem& problem = mModel.problems()[r];
    const double tau = mModel.settings.maxWeightChange;
    std::vector<SimplexSolution>& solutions = batch.out<Array::Solutions>();
    const SimplexSolution* previous = nullptr;
    if (tau > 0) {
      previous =
          i > 0 ? &solutions[item - regionCount] : (mPrevious.empty() ? nullptr : &mPrevious[r]);
    }
    try {
      if (previous != nullptr) {
        const Eigen::VectorXd lower = (previous->weights.array() - tau).cwiseMax(0.0).matrix();
        const Eigen::VectorXd upper = (previous->weights.array() + tau).cwiseMin(1.0).matrix();
        solutions[item] = problem.solver->solveProjected(p, rr, bb, lower, upper);
      } else {
        solutions[item] = problem.solver->solveProjected(p, rr, bb);
      }
    } catch (const Error& error) {
      DS_THROW(kNumerical, "frame ", batch.in<Array::Frames>()[i],
               regionCount > 1 ? " region '" + problem.name + "'" : std::string(), ": ",
               error.what());
    }
  }

  void recordSolutions(Batch& batch, int i, FrameRecord& record) {
    const int k = mModel.k, regionCount = mModel.regionCount();
    record.weights.clear();
    record.atZero.clear();
    record.atOne.clear();
    record.relativeResidual = record.kktResidual = 0.0;
    record.iterations = 0;
    for (int r = 0; r < regionCount; ++r) {
      const SimplexSolution& s = batch.in<Array::Solutions>()[(batch.warm() + i) * regionCount + r];
      record.weights.insert(record.weights.end(), s.weights.data(), s.weights.data() + k);
      for (int z : s.atZero) {
        record.atZero.push_back(r * k + z);
      }
      for (int o : s.atOne) {
        record.atOne.push_back(r * k + o);
      }
      record.relativeResidual = std::max(record.relativeResidual, s.relativeResidual);
      record.kktResidual = std::max(record.kktResidual, s.kktResidual);
      record.iterations += s.iterations;
    }
  }

  /// ||sum_i w_i P_i - b|| / ||b|| on each weight problem's rows (the aligned shapes P_i and
  /// frame b), in double, the largest over regions: the fit error without the QP objective's
  /// cancellation.
  double directResidual(const float* frame, const std::vector<double>& weights) const {
    const int k = mModel.k;
    const std::size_t dv = mModel.driverValues;
    double worst = 0.0;
    std::vector<double> fit;
    const std::vector<WeightProblem>& problems = mModel.problems();  // built by solve()
    for (std::size_t r = 0; r < problems.size(); ++r) {
      // The values of the problem's rows: every value of the frame, or 3 per listed row.
      const std::vector<int>& rows = problems[r].rows;
      const std::size_t values = rows.empty() ? dv : 3 * rows.size();
      const auto index = [&](std::size_t i) {
        return rows.empty() ? i : 3 * static_cast<std::size_t>(rows[i / 3]) + i % 3;
      };
      fit.assign(values, 0.0);
      for (int s = 0; s < k; ++s) {
        const double w = weights[r * k + static_cast<std::size_t>(s)];
        if (w == 0.0) {
          continue;  // shapes held at 0 (most of them) add nothing
        }
        const float* shape = &mModel.driverShapes[static_cast<std::size_t>(s) * dv];
        if (rows.empty()) {
          for (std::size_t i = 0; i < values; ++i) {
            fit[i] += w * shape[i];
          }
        } else {
          for (std::size_t i = 0; i < values; ++i) {
            fit[i] += w * shape[index(i)];
          }
        }
      }
      double error2 = 0.0, norm2 = 0.0;
      for (std::size_t i = 0; i < values; ++i) {
        const double b = frame[index(i)];
        error2 += (fit[i] - b) * (fit[i] - b);
        norm2 += b * b;
      }
      worst = std::max(worst, norm2 > 0.0 ? std::sqrt(error2 / norm2) : 0.0);
    }
    return worst;
  }

  /// The nearest-shape baseline: weight 1 on the closest database driver shape.
  void nearest(const float* frame, FrameRecord& record) const {
    const Eigen::VectorXd b =
        Eigen::Map<const Eigen::VectorXf>(frame, mModel.driverValues).cast<double>();
    Eigen::Index best = 0;
    const double distance = (mShapes.colwise() - b).colwise().squaredNorm().minCoeff(&best);
    record.weights.assign(mModel.k, 0.0);
    record.weights[best] = 1.0;
    record.atZero.clear();
    record.atOne.clear();
    record.kktResidual = 0.0;
    record.iterations = 0;
    record.relativeResidual = b.norm() > 0 ? std::sqrt(distance) / b.norm() : 0.0;
  }

  Model& mModel;
  Eigen::MatrixXd mShapes;                 ///< nearest: the aligned driver shapes, 3Vp x k
  std::vector<SimplexSolution> mPrevious;  ///< temporal bound: the last frame's solutions
};

}  // namespace

std::unique_ptr<Stage> makeWeightsStage(Model& model) {
  if (model.settings.weightMode == WeightMode::kBind ||
      model.settings.weightMode == WeightMode::kModel) {
    return nullptr;
  }
  return std::make_unique<WeightsStage>(model);
}

}  // namespace drivenshape::pipeline
