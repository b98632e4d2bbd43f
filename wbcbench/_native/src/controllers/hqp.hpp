// The conventional hierarchical QP (OSF-HQP paper §II, eq. 2–15): the native mirror of
// wbcbench/controllers/hqp.py. Variables x = (q̈ (n), Γ (k), f (6c)); the dynamics, stationary
// contacts, wrench inequalities and torque limits hard at every level; one level per task
// priority; final regularisation levels resolve what redundancy is left.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <memory>
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
  // once the tasks are added: the levels and hard constraints of the contact set the tick
  // holds. Each contact set has a workspace of its own (its settings, constraints and levels),
  // made by its first configure and kept: a change to a set configured before switches to it
  // and allocates nothing.
  void configure(const HqpSettings& settings);
  // the whole tick at (q, v, t), its QPs solved by `solver`; false when it failed
  bool run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t,
           LevelSolver& solver);
  int handles() const;
  // the wrench rows' bounds of this tick (a contact schedule's ramps), into the hard rows
  void set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                         const Eigen::Ref<const Vector>& uw) override;

  // the last run's hierarchy result (valid until the next run; empty when the run stopped
  // before the hierarchy: a NaN in its data)
  const HierarchyResult& result() const;
  const Hierarchy& hierarchy() const { return hierarchy_; }
  const Vector& tau() const { return tau_; }
  const Vector& qdd() const { return qdd_; }
  const Vector& wrench() const;

 private:
  // what depends on the contact set
  struct Workspace {
    HqpSettings s;
    int nc = 0, n_levels = 0;
    HardConstraints hard;
    std::vector<PriorityLevel> soft;  // the priorities, then the finals
    Matrix K;  // the rigid-contact KKT matrix of the zero-torque motion
    Eigen::CompleteOrthogonalDecomposition<Matrix> kkt;
    Vector rhs, qdd0, wrench;
  };
  void contacts_switched(int set) override;
  Workspace& work();

  int n_ = 0, k_ = 0;
  std::vector<std::unique_ptr<Workspace>> work_;  // by contact set number (null: not configured)
  Workspace* w_ = nullptr;                        // the current set's
  Hierarchy hierarchy_;
  bool solved_ = false;  // the last run solved the hierarchy
  Eigen::LLT<Matrix> llt_;
  Vector tau_, qdd_;
};

}  // namespace wbcbench
