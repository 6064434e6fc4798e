// SPDX-License-Identifier: Apache-2.0
// Projections p = M^T (b - m) per frame and weight problem, and the norms the QP needs: one
// backend launch for the whole-driver QP, the host for region rows (docs/architecture.md, "The path
// of one driver frame").

#include "parallel.h"

#include "../stage.h"

namespace drivenshape::pipeline {
namespace {

class ProjectStage final : public Stage {
 public:
  explicit ProjectStage(Model& model) : mModel(model) {
    declare({Array::Aligned}, {Array::Projections, Array::Norms, Array::HostProjections});
    model.problems();
  }

  const char* name() const override { return "project"; }

  void run(Batch& batch) override {
    const int n = batch.solveCount(), k = mModel.k;
    const int regionCount = mModel.regionCount();
    std::vector<float>& projections = batch.out<Array::Projections>();
    std::vector<float>& norms = batch.out<Array::Norms>();
    std::vector<double>& hostProjections = batch.out<Array::HostProjections>();
    projections.assign(static_cast<std::size_t>(n) * regionCount * (k - 1), 0.0f);
    norms.assign(static_cast<std::size_t>(n) * regionCount * 2, 0.0f);
    hostProjections.clear();
    if (!mModel.settings.regions) {
      mModel.stages().projectBlock(n, batch.alignedAll(), projections.data(), norms.data());
      return;
    }
    hostProjections.assign(static_cast<std::size_t>(n) * regionCount * (k + 1), 0.0);
    const float* aligned = batch.in<Array::Aligned>();
    parallelFor(n * regionCount, mModel.threads, [&](int item) {
      const int i = item / regionCount, r = item % regionCount;
      const WeightProblem& problem = mModel.problems()[r];
      const float* frame = aligned + i * mModel.driverValues;
      Eigen::VectorXd b(static_cast<Eigen::Index>(problem.rows.size()) * 3);
      for (std::size_t j = 0; j < problem.rows.size(); ++j) {
        for (int c = 0; c < 3; ++c) {
          b(static_cast<Eigen::Index>(3 * j + c)) = frame[3 * problem.rows[j] + c];
        }
      }
      const Eigen::VectorXd d = b - problem.solver->center();
      double* out = &hostProjections[static_cast<std::size_t>(item) * (k + 1)];
      Eigen::Map<Eigen::VectorXd>(out, k - 1) = problem.solver->basis().transpose() * d;
      out[k - 1] = d.squaredNorm();
      out[k] = b.squaredNorm();
    });
  }

 private:
  Model& mModel;
};

}  // namespace

std::unique_ptr<Stage> makeProjectStage(Model& model) {
  if (model.settings.weightMode != WeightMode::kQp) {
    return nullptr;
  }
  return std::make_unique<ProjectStage>(model);
}

}  // namespace drivenshape::pipeline
