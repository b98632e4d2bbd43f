// The conventional lexicographic QP on the full model (RC-LQP paper §2, §4.1, Table 1): the
// native mirror of wbcbench/controllers/lqp.py. Variables x = (q̈ (n), f (6c)), the torque
// eliminated through the actuated rows of the dynamics, Γ = G x + γ.
#pragma once

#include <Eigen/Cholesky>
#include <memory>
#include <string>
#include <vector>

#include "controllers/tick.hpp"
#include "qp/hierarchy.hpp"

namespace wbcbench {

// What both LQPs (conventional and reduced-centroidal) take once.
struct LexicographicSettings {
  Strategy strategy = Strategy::kNullspace;
  double qdd_limit = 300.0;              // |q̈_j| of actuated joints [rad/s²]
  double wrench_regularization = 1e-4;   // weight of ‖f‖² next to the acceleration energy
  double prox = 1e-8;                    // proximal weight of a failed level's retry
  double accept_tol = 1e-5;              // HierarchyOptions::accept_tol
  double final_weight = 1e-4;            // the energy's weight in the last level's cost
  std::vector<double> weights;           // weighted strategy: per level (the last repeats)
  std::vector<std::vector<int>> groups;  // task indices of each priority, highest first
  std::vector<int> priorities;           // the priority of each group (level names p<i>)
  Vector tau_max;                        // (k,)
  Matrix Cw;                             // wrench inequalities (nw, 6c)
  Vector lw, uw;
};

// The full-model LQP of one tick's dynamics and tasks: its levels, its hierarchy, the answer.
// Each contact set has a workspace of its own (its settings, constraints and levels), made by
// its first configure and kept: a return to a set configured before (select) allocates nothing.
class FullLqp {
 public:
  // pool: the id the hierarchy's solves carry; prefix: put before every level name
  explicit FullLqp(int pool = 0, std::string prefix = "") : hierarchy_(pool), prefix_(prefix) {}
  // nc: the contact rows (force variables); nk: the independent ones (constraint rows); set:
  // the number of the contact set these are for (its workspace is made or re-made)
  void configure(const LexicographicSettings& settings, int n, int nc, int nk, int set = 0);
  // the workspace of contact set `set` (none until that set is configured)
  void select(int set);
  // the hierarchy at this tick's dynamics and tasks; false when a level failed (failed_level)
  // or the data hold a NaN (failed_level empty)
  bool solve(const RobotDynamics& dyn, const TaskSet& tasks, LevelSolver& solver);
  int handles() const { return w_ == nullptr ? 0 : 2 * static_cast<int>(w_->levels.size()); }
  // the wrench rows' bounds of this tick (a contact schedule's ramps), into the contacts level
  void set_wrench_bounds(const Eigen::Ref<const Vector>& lw, const Eigen::Ref<const Vector>& uw);

  // the last solve's result (valid until the next solve; empty when it stopped before the
  // hierarchy: a NaN in its data)
  const HierarchyResult& result() const;
  // seconds inside the solver calls of the last solve()
  double solver_seconds() const { return solver_seconds_; }
  const Hierarchy& hierarchy() const { return hierarchy_; }
  const Vector& tau() const { return tau_; }
  const Vector& qdd() const { return qdd_; }
  const Vector& wrench() const;

 private:
  // what depends on the contact set
  struct Workspace {
    LexicographicSettings s;
    int nc = 0, nk = 0;
    HardConstraints hard;
    std::vector<PriorityLevel> levels;  // contacts, the task priorities, then the energy
    Matrix G;
    Vector gamma, wrench;
  };
  Workspace& work();

  int n_ = 0, k_ = 0;
  std::vector<std::unique_ptr<Workspace>> work_;  // by contact set number (null: not configured)
  Workspace* w_ = nullptr;                        // the current set's
  Hierarchy hierarchy_;
  bool solved_ = false;  // the last solve reached the hierarchy
  std::string prefix_;
  double solver_seconds_ = 0.0;
  Eigen::LLT<Matrix> llt_;
  Vector tau_, qdd_;
};

class LqpTick : public Tick {
 public:
  LqpTick(const std::string& model, const std::vector<std::string>& task_frames,
          const std::vector<std::string>& contact_frames);
  void configure(const LexicographicSettings& settings);
  // the whole tick at (q, v, t), its QPs solved by `solver`; false when it failed
  bool run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t,
           LevelSolver& solver);
  const FullLqp& lqp() const { return lqp_; }
  void set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                         const Eigen::Ref<const Vector>& uw) override {
    lqp_.set_wrench_bounds(lw, uw);
  }

 private:
  void contacts_switched(int set) override { lqp_.select(set); }
  FullLqp lqp_;
};

// NaN anywhere in the dynamics or tasks a hierarchy is built from
bool dynamics_finite(const RobotDynamics& dyn, const TaskSet& tasks);

}  // namespace wbcbench
