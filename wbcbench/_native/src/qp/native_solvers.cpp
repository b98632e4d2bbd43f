#include "qp/native_solvers.hpp"

#include <chrono>

namespace wbcbench {

void NativeSolvers::set(int pool, int handle, std::shared_ptr<QpSolver> solver) {
  solvers_[{pool, handle}] = std::move(solver);
}

void NativeSolvers::clear() {
  records_.clear();
  failed_ = -1;
  keep_seconds_ = 0.0;
}

void NativeSolvers::reset() {
  clear();
  for (auto& [key, solver] : solvers_) solver->reset();
}

bool NativeSolvers::solve(int pool, int handle, const std::string& level, const QpBuffers& qp,
                          Vector& x, Vector& z, bool& has_z) {
  QpSolver& solver = *solvers_.at({pool, handle});
  const QpOutcome& outcome = solver.solve(qp);
  records_.push_back({pool, handle, level, outcome, nullptr, nullptr});
  if (keep_) {
    const auto t0 = std::chrono::steady_clock::now();
    records_.back().qp = std::make_shared<const QpBuffers>(qp);
    records_.back().sol = std::make_shared<const QpSolution>(solver.solution());
    keep_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  if (!outcome.success()) {
    failed_ = static_cast<int>(records_.size()) - 1;
    return false;
  }
  const QpSolution& sol = solver.solution();
  x = sol.x;
  has_z = sol.has_z;
  if (has_z) z = sol.z;
  return true;
}

}  // namespace wbcbench
