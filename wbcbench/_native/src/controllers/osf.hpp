// The two OSF controllers' ticks: the native mirrors of wbcbench/controllers/to_osf.py (TO-OSF,
// one QP over the task references and an internal wrench) and osf_hqp.py (OSF-HQP, one small QP
// per priority level, then a wrench QP). Both read the operational-space parameters of
// dynamics/osf.hpp, computed in the loop every `period` ticks (params: inline | periodic:N) or
// on a worker thread (params: async, controllers/params_worker.hpp).
#pragma once

#include <string>
#include <vector>

#include "controllers/params_worker.hpp"
#include "controllers/tick.hpp"
#include "dynamics/osf.hpp"

namespace wbcbench {

// What both OSF ticks take once. Tasks are added in level order (highest priority first), so
// every level is a block of rows of the stacked tasks.
struct OsfSettings {
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
  Vector acc_bound;             // |ẍ_opt| bound per task row (inf: none)
};

struct ToOsfSettings : OsfSettings {
  Vector row_weights;           // H per task row
  double wrench_weight = 1.0;   // H_w
  bool wrench_total = true;     // S_f on the total wrench (else on F_opt only)
  double regularization = 1e-3;
  Matrix Sf;                    // wrench selection (rows kept, 6c)
};

struct OsfHqpSettings : OsfSettings {
  double regularization = 1e-6;
  double carry_tolerance = 1e-6;
  Matrix WtW;                   // W_cᵀ W_c (6c, 6c)
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

 protected:
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
  RowMatrix partial_;
  Vector tau_, qdd_, wrench_, work_;
  std::string message_;
};

class ToOsfTick : public OsfTick {
 public:
  using OsfTick::OsfTick;
  void configure(const ToOsfSettings& settings);
  // dynamics, tasks, parameters and the QP; false when the QP holds a NaN
  bool build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);
  // τ, q̈ and the wrench from the QP's solution (scaled variables)
  void finish(const Eigen::Ref<const Vector>& x);
  QpBuffers& qp() { return qp_; }
  const Vector& rho() const { return rho_; }  // the optimised task references

 private:
  ToOsfSettings s_;
  int nx_ = 0;
  double scale_ = 1.0, w_f_ = 1.0;
  Vector D_, h_task_, rho_, f_opt_, fc_, prev_;
  Matrix Af_, SA_;
  QpBuffers qp_;
};

class OsfHqpTick : public OsfTick {
 public:
  using OsfTick::OsfTick;
  void configure(const OsfHqpSettings& settings);
  // dynamics, tasks, parameters and the first level's QP; false when the QP holds a NaN or the
  // wrench-distribution space changed dimension (see message())
  bool build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);
  // level i's solution: its torque, then the next QP (a level's, or the wrench QP)
  bool level(int i, const Eigen::Ref<const Vector>& x);
  // the wrench QP's solution (empty when there is none): τ, q̈ and the wrench
  void finish(const Eigen::Ref<const Vector>& x);
  // the QPs: one per level, then the wrench QP where there is a distribution space
  int n_qps() const { return static_cast<int>(qps_.size()); }
  QpBuffers& qp(int i) { return qps_.at(i); }
  const Vector& slack_norms() const { return slack_; }

 private:
  void build_level(int i);
  void build_wrench();

  OsfHqpSettings s_;
  int np_ = 0;
  std::vector<QpBuffers> qps_;
  Vector base_, cw_f0_, slack_, ftask_;
  Matrix CwF_, CwQ_, QW_;
};

}  // namespace wbcbench
