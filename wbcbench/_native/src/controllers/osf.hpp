// What the two OSF controllers' ticks share (to_osf.hpp, osf_hqp.hpp; the native mirror of
// OsfControllerBase in wbcbench/controllers/to_osf.py): the operational-space parameters of
// dynamics/osf.hpp, computed in the loop every `period` ticks (params: inline | periodic:N) or
// on a worker thread (params: async, controllers/params_worker.hpp), and the torque they realise.
#pragma once

#include <memory>
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

// What a contact set fixes in an OSF tick: its settings, the parameters' model and buffers (and
// worker, params: async), the level rows it picks and the sizes. A controller extends it with
// its QPs (to_osf.hpp, osf_hqp.hpp).
struct OsfWorkspace {
  virtual ~OsfWorkspace() = default;
  OsfSettings os;
  std::unique_ptr<OsfModel> model;
  std::unique_ptr<ParamsWorker> worker;  // params: async, from the second tick on
  OsfParams params;
  bool have_params = false;  // params hold a set computed since the tick last switched here
  int nc = 0, nw = 0, nr = 0;
  std::vector<int> offsets;  // first row of each level
  bool picked = false;       // the levels hold a subset of the tasks: gathered into J …
  Matrix J;
  Vector drift, ref;
  RowMatrix partial;  // the cumulative torques Γ_{≤1} … Γ_{≤L} (L, k)
  Vector wrench;
  Vector level_work;  // OsfParams::level_step's scratch (the most rows of a level)
};

// The parameters' part of a tick: the model, the current set, when it was computed. Each contact
// set has a workspace of its own (OsfWorkspace), made by its first configure and kept: a change
// to a set configured before switches to it and allocates nothing.
class OsfTick : public Tick {
 public:
  using Tick::Tick;

  const OsfParams& params() const { return w().params; }
  long staleness() const { return tick_ - w().params.tick; }
  const std::string& message() const { return message_; }
  // parameter sets the worker threads computed (params: async), and stopping them
  long worker_sets() const;
  void close();
  // the cumulative torques Γ_{≤1} … Γ_{≤L} of the last tick (L, k)
  const RowMatrix& partial() const { return w().partial; }
  const Vector& tau() const { return tau_; }
  const Vector& qdd() const { return qdd_; }
  const Vector& wrench() const { return w().wrench; }
  // the level tasks' stacked rows (those OsfSettings::tasks picks), in level order
  const Matrix& level_J() const { return w().picked ? w().J : tasks_.J(); }
  const Vector& level_drift() const { return w().picked ? w().drift : tasks_.drift(); }
  const Vector& level_ref() const { return w().picked ? w().ref : tasks_.acc_ref(); }
  // Sizes what the contact set's first tick would: its parameters' model and buffers, computed
  // once at (q, v, t) (a state of the run's start; the result is dropped: the set's first tick
  // computes its own), so that a change to the set allocates nothing in the tick. After
  // configure.
  void prepare(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);

 protected:
  // configure() for the contact set the tick holds: its workspace (made on the first call for
  // the set, refilled on a later one) takes the settings; the parameters of any other set are
  // never used (the set's next tick computes a set for it)
  void configure_osf(const OsfSettings& s, bool affine);
  // dynamics, tasks and (when due) the parameters at (q, v, t); the tick counter advances
  void evaluate_osf(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                    double t);
  // the level tasks' rows, in level order, into w's J, drift and ref (when it picks)
  void gather(OsfWorkspace& w);
  // τ = Γ_{≤L} + dist, and what it realises
  void realise(const Vector& dist);
  int levels() const { return static_cast<int>(w().os.level_dims.size()); }
  // a new, empty workspace of the controller's kind
  virtual std::unique_ptr<OsfWorkspace> make_workspace() const = 0;
  // the workspace of the set the tick holds (configure first)
  OsfWorkspace& w();
  const OsfWorkspace& w() const;
  void contacts_switched(int set) override;

  std::vector<std::unique_ptr<OsfWorkspace>> work_;  // by contact set number (null: none yet)
  OsfWorkspace* w_ = nullptr;                        // the current set's
  long tick_ = -1;  // ticks since the tick was made (the parameters' tick numbers)
  Vector tau_, qdd_;
  std::string message_;
};

}  // namespace wbcbench
