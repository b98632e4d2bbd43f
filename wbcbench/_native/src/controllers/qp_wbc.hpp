// The weighted QP-WBC's tick (TO-OSF paper §V-A, eq. 22–25): the native mirror of
// wbcbench/controllers/qp_wbc.py, variables (q̈, Γ, f) ("full") or (q̈, f) ("eliminated").
#pragma once

#include <memory>
#include <vector>

#include "controllers/tick.hpp"

namespace wbcbench {

struct QpWbcSettings {
  bool eliminated = false;
  Vector row_weights;  // one weight per stacked task row
  double acceleration_weight = 0.0, torque_weight = 0.0, wrench_weight = 0.0;
  Vector tau_max;      // (k,)
  Matrix Cw;           // wrench inequalities (nw, 6c)
  Vector lw, uw;
};

class QpWbcTick : public Tick {
 public:
  QpWbcTick(const std::string& model, const std::vector<std::string>& task_frames,
            const std::vector<std::string>& contact_frames);

  // once the tasks are added: sizes the QP of the contact set the tick holds and fills its
  // constant parts. Each contact set has a workspace of its own (its settings, its QP buffers),
  // made by its first configure and kept: a change to a set configured before switches to its
  // workspace and allocates nothing (the QP buffers, whose NumPy views Python holds, stay put).
  void configure(const QpWbcSettings& settings);
  // dynamics, tasks and the QP at (q, v, t); false when the QP holds a NaN
  bool build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);
  // τ, q̈ and the wrenches from the QP's solution x
  void finish(const Eigen::Ref<const Vector>& x);
  // the wrench rows' bounds of this tick (a contact schedule's ramps), into the QP's l and u
  void set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                         const Eigen::Ref<const Vector>& uw) override;

  // the QP of the contact set the tick holds (configure() first)
  QpBuffers& qp();
  const Vector& tau() const { return tau_; }
  const Vector& qdd() const { return qdd_; }
  const Vector& wrench() const;

 private:
  // what depends on the contact set
  struct Workspace {
    QpWbcSettings s;
    int nc = 0, nk = 0, nx = 0;
    QpBuffers qp;
    RowMatrix G;  // Γ = G x + γ (eliminated)
    Vector gamma, wrench;
  };
  void contacts_switched(int set) override;
  Workspace& work();

  int n_ = 0, k_ = 0;
  std::vector<std::unique_ptr<Workspace>> work_;  // by contact set number (null: not configured)
  Workspace* w_ = nullptr;                        // the current set's
  Matrix JW_;  // task rows scaled by their weights (rows, n)
  Vector r_;   // ẍ* − J̇ q̇ of every task row
  Vector tau_, qdd_;
};

}  // namespace wbcbench
