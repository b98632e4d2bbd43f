// What the two OSF controllers' ticks share (to_osf.hpp, osf_hqp.hpp; the native mirror of
// OsfControllerBase in wbcbench/controllers/to_osf.py): the operational-space parameters of
// dynamics/osf.hpp, computed in the loop every `period` ticks (params: inline | periodic:N) or
// on a worker thread (params: async, controllers/params_worker.hpp), and the torque they realise.
#pragma once

#include <string>
#include <vector>

#include "controllers/params_worker.hpp"
#include "controllers/tick.hpp"
#include "dynamics/osf.hpp"

namespace wbcbench {

// What both OSF ticks take for a contact set. Tasks are added in level order (highest priority
// first); `tasks` picks those of the levels (a swing task of a standing foot leaves them), so
// every level is a block of rows of the picked tasks.
struct OsfSettings {
  std::vector<int> tasks;       // indices into the tick's tasks, in level order (empty: all)
  std::vector<int> level_dims;
  std::vector<bool> force_level;
  std::string inverse = "cod";  // cod | svd | pinv
  bool exact = true;            // coupling: exact | literal
  double rcond = 1e-9;
  int period = 1;               // parameters recomputed every `period` ticks (inline: 1)
  bool asynchronous = false;    // params: async — on a worker thread after the first tick
  Vector tau_max;               // (k,)
  Matrix Cw;                    // wrench inequalities (nw, 6c)
  Vector lw, uw;
  Vector acc_bound;             // |ẍ_opt| bound per level task row (inf: none)
};

// The parameters' part of a tick: the model, the current set, when it was computed.
class OsfTick : public Tick {
 public:
  using Tick::Tick;

  const OsfParams& params() const { return params_; }
  long staleness() const { return tick_ - params_.tick; }
  const std::string& message() const { return message_; }
  // parameter sets the worker thread computed (params: async), and stopping it
  long worker_sets() const { return worker_ ? worker_->computed() : 0; }
  void close() { worker_.reset(); }
  // the cumulative torques Γ_{≤1} … Γ_{≤L} of the last tick (L, k)
  const RowMatrix& partial() const { return partial_; }
  const Vector& tau() const { return tau_; }
  const Vector& qdd() const { return qdd_; }
  const Vector& wrench() const { return wrench_; }
  // the level tasks' stacked rows (those OsfSettings::tasks picks), in level order
  const Matrix& level_J() const { return picked_ ? J_ : tasks_.J(); }
  const Vector& level_drift() const { return picked_ ? drift_ : tasks_.drift(); }
  const Vector& level_ref() const { return picked_ ? ref_ : tasks_.acc_ref(); }

 protected:
  // configure() again for a new contact set re-sizes what depends on it and drops the
  // parameters of the old set: the next tick computes a set for the new one
  void configure_osf(const OsfSettings& s, bool affine);
  // dynamics, tasks and (when due) the parameters at (q, v, t); the tick counter advances
  void evaluate_osf(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                    double t);
  // τ = Γ_{≤L} + dist, and what it realises
  void realise(const Vector& dist);
  int levels() const { return static_cast<int>(os_.level_dims.size()); }

  OsfSettings os_;
  std::unique_ptr<OsfModel> model_;
  std::unique_ptr<ParamsWorker> worker_;  // params: async, from the second tick on
  OsfParams params_;
  bool have_params_ = false;
  long tick_ = -1;
  int nc_ = 0, nw_ = 0, nr_ = 0;
  std::vector<int> offsets_;  // first row of each level
  bool picked_ = false;       // the levels hold a subset of the tasks: gathered into J_ …
  Matrix J_;
  Vector drift_, ref_;
  RowMatrix partial_;
  Vector tau_, qdd_, wrench_, work_;
  std::string message_;
};

}  // namespace wbcbench
