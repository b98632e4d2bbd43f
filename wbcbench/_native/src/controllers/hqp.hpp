// The conventional hierarchical QP (OSF-HQP paper §II, eq. 2–15): the native mirror of
// wbcbench/controllers/hqp.py. Variables x = (q̈ (n), Γ (k), f (6c)); the dynamics, stationary
// contacts, wrench inequalities and torque limits hard at every level; one level per task
// priority; final regularisation levels resolve what redundancy is left.
#pragma once

#include <string>
#include <vector>

#include "controllers/tick.hpp"
#include "qp/hierarchy.hpp"

namespace wbcbench {

enum class HqpFinal { kTorque, kWrench, kAccelerationEnergy, kZeroTorqueEnergy };

struct HqpSettings {
  Strategy strategy = Strategy::kCascade;
  std::vector<HqpFinal> finals;
  Vector wrench_weights;                 // W_c diagonal per contact (6,) for the wrench final
  double prox = 1e-8;                    // proximal weight of a failed level's retry
  double accept_tol = 1e-5;              // HierarchyOptions::accept_tol
  std::vector<double> level_weights;     // weighted strategy: per priority (the last repeats)
  std::vector<std::vector<int>> groups;  // task indices of each priority, highest first
  std::vector<int> priorities;           // the priority of each group (level names L<p>)
  std::vector<bool> force_level;         // per task: a torque-level joint task
  Vector tau_max;                        // (k,)
  Matrix Cw;                             // wrench inequalities (nw, 6c)
  Vector lw, uw;
};

class HqpTick : public Tick {
 public:
  HqpTick(const std::string& model, const std::vector<std::string>& task_frames,
          const std::vector<std::string>& contact_frames);
  void configure(const HqpSettings& settings);
  // the whole tick at (q, v, t), its QPs solved by `solver`; false when it failed
  bool run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t,
           LevelSolver& solver);
  int handles() const;
  // the wrench rows' bounds of this tick (a contact schedule's ramps), into the hard rows
  void set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                         const Eigen::Ref<const Vector>& uw) override;

  const HierarchyResult& result() const { return result_; }
  const Hierarchy& hierarchy() const { return hierarchy_; }
  const Vector& tau() const { return tau_; }
  const Vector& qdd() const { return qdd_; }
  const Vector& wrench() const { return wrench_; }

 private:
  HqpSettings s_;
  int n_ = 0, k_ = 0, nc_ = 0, n_levels_ = 0;
  Hierarchy hierarchy_;
  HardConstraints hard_;
  std::vector<PriorityLevel> soft_;  // the priorities, then the finals
  HierarchyResult result_;
  Matrix K_;  // the rigid-contact KKT matrix of the zero-torque motion
  Vector tau_, qdd_, wrench_, rhs_;
};

}  // namespace wbcbench
