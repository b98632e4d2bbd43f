// The reduced-centroidal LQP (RC-LQP paper §3–4): the native mirror of
// wbcbench/controllers/rc_lqp.py, whose module docstring states the mathematics and every
// option. LQP 1 over x₁ = (q̈_r (n_r), f (6c)) on the reduced model (ReducedDynamics), LQP 2
// over x₂ = q̈_uc on the unconstrained chains, the chains' centroidal preview, the exact and the
// paper's torque assembly, the step's checks and, when eq. (30) cannot be met, the re-plan and
// the full-model LQP (FullLqp) as the last resort. The functions keep the reference's names.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/SVD>
#include <memory>
#include <string>
#include <vector>

#include "controllers/lqp.hpp"
#include "controllers/tick.hpp"
#include "dynamics/reduced.hpp"
#include "qp/hierarchy.hpp"

namespace wbcbench {

enum class Assembly { kExact, kPaper };
enum class CentroidPreview { kPriority, kEnergy, kOff };
enum class Lqp2Energy { kWhole, kChain };
enum class InfeasibleCoupling { kReplan, kFail };

// RcLqpConfig's own settings (the shared ones are LexicographicSettings).
struct RcLqpSettings {
  Assembly assembly = Assembly::kExact;
  bool coupling_priority = false;
  CentroidPreview centroid_preview = CentroidPreview::kPriority;
  Lqp2Energy lqp2_energy = Lqp2Energy::kWhole;
  bool diagnostics = false;  // assembly_diff under the exact assembly
  double coupling_tol = 1e-6;
  double wrench_tol = 1e-3;  // relative to max(1, |f|_inf)
  InfeasibleCoupling infeasible_coupling = InfeasibleCoupling::kReplan;
};

// The hierarchies of one tick, each with its own solver handles (the `pool` its solves carry),
// in the order of the reference's SolverPools: pool1, pool2, pool1b, pool2b (coupling_priority's
// re-solve), pool1c, pool2c (the re-plan), pool2r (the reachable centroidal acceleration) and
// the full-model LQP's; so that warm and hot handles see the same problems in both impls.
enum RcLqpPool : int {
  kPoolLqp1 = 0,
  kPoolLqp2,
  kPoolLqp1Coupling,
  kPoolLqp2Coupling,
  kPoolLqp1Replan,
  kPoolLqp2Replan,
  kPoolLqp2Reach,
  kPoolFallback,
  kRcLqpPools
};

class RcLqpTick : public Tick {
 public:
  // stances: the chain split of each contact set the tick may hold
  // (wbcbench.dynamics.chains.split_chains, computed in Python once per set), each for a subset
  // of `contact_frames` in their order; the first for every contact frame (the set the tick
  // holds until select_contacts). A reduced model is built for each, here, and kept.
  RcLqpTick(const std::string& model, const std::vector<std::string>& task_frames,
            const std::vector<std::string>& contact_frames,
            const std::vector<SplitSpec>& stances);
  // one more stance (a contact set first met after set-up); nothing if its set has one
  void add_stance(const SplitSpec& split);
  // the contacts the tick holds and the reduced model of their stance (RcLqp.contacts_changed);
  // the settings and the row split for the new set follow (configure, set_row_split). Throws
  // std::invalid_argument for a set with no stance.
  bool select_contacts(const std::vector<int>& active) override;
  // the ramped bounds into LQP 1's contacts level, the wrench check and the full-model LQP's
  void set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                         const Eigen::Ref<const Vector>& uw) override;
  void configure(const LexicographicSettings& settings, const RcLqpSettings& rc);
  // the whole tick at (q, v, t), its QPs solved by `solver`; false when it failed (message(),
  // and when a hierarchy failed, level_failed() and failed_level())
  bool run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t,
           LevelSolver& solver);

  // the row split of RcLqp.row_split: per task (the tick's order), the task's rows that go to
  // LQP 1 (none for a task the configured groups do not hold); set after every configure,
  // before the next run
  void set_row_split(const std::vector<std::vector<int>>& lqp1_rows);

  // solver handles pool `pool` may use (a bound: the level count depends on the row split)
  int handles(int pool) const;
  const QpBuffers& slot(int pool, int i) const;

  const Vector& tau() const { return tau_; }
  const Vector& qdd() const { return qdd_; }
  const Vector& wrench() const { return wrench_; }
  // LQP 1 and LQP 2 of the plan (after coupling_priority's re-solve; before any re-plan): the
  // slacks the step reports
  const HierarchyResult& lqp1() const { return res1_; }
  const HierarchyResult& lqp2() const { return res2_; }
  bool has_lqp2() const { return has_res2_; }
  int retries() const { return retries_; }
  bool replanned() const { return replanned_; }
  bool fell_back() const { return fell_back_; }
  // the diagnostics of the step (NaN where the reference has no such key)
  double base_residual() const { return base_residual_; }
  double wrench_residual() const { return wrench_residual_; }
  double coupling_residual() const { return coupling_residual_; }
  double assembly_diff() const { return assembly_diff_; }
  double coupling_violation() const { return coupling_violation_; }
  // a failed tick: why; when a hierarchy failed (level_failed), the caller appends the failed
  // level's solver message to message()
  const std::string& message() const { return message_; }
  bool level_failed() const { return level_failed_; }
  const std::string& failed_level() const { return failed_level_; }
  // why that level's answer was refused although reported solved (HierarchyResult::message)
  const std::string& failed_reason() const { return failed_reason_; }
  // stage times of the last tick [s]: the reduced model, each LQP (formulation + solve) and
  // the full-model LQP (0 when it did not run)
  double reduced_time() const { return reduced_time_; }
  double lqp1_time() const { return lqp1_time_; }
  double lqp2_time() const { return lqp2_time_; }
  double fallback_time() const { return fallback_time_; }

  const ReducedDynamics& reduced() const { return *reduced_; }
  // the row split (task rows of each priority group, as rows of the stacked tasks) and the
  // preview d = D q̈_p + d0 of the last tick, for tests
  const std::vector<std::vector<int>>& lqp1_rows() const { return rows1_; }
  const std::vector<std::vector<int>>& lqp2_rows() const { return rows2_; }
  int chain_priority() const { return chain_priority_; }
  const Matrix& preview_D() const { return D_; }
  const Vector& preview_d0() const { return d0_; }

 private:
  struct Diagnostics {
    double base_residual = 0.0, coupling_residual = 0.0, assembly_diff = 0.0;
    double wrench_residual = 0.0;
  };

  void preview();
  void prepare_lqp1();
  int lqp1_levels(std::vector<PriorityLevel>& levels, bool with_preview);
  void preview_level(PriorityLevel& lv) const;
  // the pool's hierarchy's result (valid until that pool solves again)
  const HierarchyResult& solve_lqp1(int pool, const HardConstraints& hard,
                                    std::vector<PriorityLevel>& levels, int count, bool target,
                                    LevelSolver& solver);
  int lqp2_levels(std::vector<PriorityLevel>& levels, const Vector& x1, bool with_tasks,
                  bool coupling_last);
  const HierarchyResult& solve_lqp2(int pool, std::vector<PriorityLevel>& levels, int count,
                                    const Vector& x1, LevelSolver& solver);
  bool plan(bool level, bool target, LevelSolver& solver);
  bool replan(LevelSolver& solver);
  // how far f is outside the contacts' inequalities lw <= Cw f <= uw (0 inside)
  double wrench_violation(const Vector& f);
  std::string assemble(const Vector& x1, const Vector* x2, Vector& qdd, Vector& f, Vector& tau,
                       Diagnostics& d);
  bool fail(const std::string& prefix, const HierarchyResult& result);
  HierarchyOptions options(int count) const;

  LexicographicSettings s_;
  RcLqpSettings rc_;
  // the reduced model of each stance (built once, kept) and the one of the held contacts
  std::vector<std::unique_ptr<ReducedDynamics>> stances_;
  ReducedDynamics* reduced_ = nullptr;
  int n_ = 0, k_ = 0, nc_ = 0, n_p_ = 0, n_r_ = 0, n_uc_ = 0, n_g_ = 0, nx1_ = 0;
  std::vector<int> plain_, uc_, act_plain_, act_uc_;
  Vector tau_max_p_, tau_max_uc_;

  // the row split, set from Python (structural) for the configured stance
  bool classified_ = false;
  std::vector<std::vector<int>> rows1_, rows2_;
  int chain_priority_ = 0;

  std::vector<std::unique_ptr<Hierarchy>> hierarchies_;  // pools kPoolLqp1 … kPoolLqp2Reach
  FullLqp fallback_;
  std::vector<std::vector<PriorityLevel>> levels_;  // per pool: the levels, then the energy
  HardConstraints hard1_, hard1r_, hard2_;          // LQP 1's, LQP 1's re-planned, LQP 2's
  Matrix C2_;                                       // LQP 1's contacts-level inequalities
  Vector l2_, u2_;
  Matrix G1_;  // constraint-chain torques Γ_p = G₁ x₁ + γ₁
  Vector gamma1_, nl_;
  Eigen::LLT<Matrix> llt_r_;  // M_r = Uᵀ U
  Matrix D_;                  // the preview d = D q̈_p + d0
  Vector d0_;
  Vector gamma2_, cross_;
  // scratch, sized at configure for every task row: a level's stacked task rows (its first
  // rows), their drift and reduced drift, their plain columns
  Matrix J_, Jp_;
  Vector v1_, v2_;
  Matrix M_up_;  // M[uc, plain] of the tick (n_uc, n_p)
  Vector x1_, reached_, w_;  // LQP 1's x kept for a re-plan; the coupling's target and w
  Vector tau_p_, qdd_uc_, uc_work_, g_work_;  // assemble's: (n_p − 6), (n_uc) twice, (n_g)
  // the preview's work per priority group with LQP 2 rows (its sizes are its rows' and the
  // ranks', which the structure fixes): kept tick to tick
  struct PreviewWork {
    Matrix J, Ju, rhs, K, Vr, coef, Z;  // Z: what is left free after this group (in u)
    Eigen::JacobiSVD<Matrix> svd;
    Vector s_r, gain;
  };
  std::vector<int> preview_groups_;  // the groups with LQP 2 rows, in order (set_row_split)
  std::vector<PreviewWork> pw_;
  Matrix pu_;  // u = u0 + B q̈_p as [u0 B] (n_uc, 1 + n_p)

  HierarchyResult res1_, res2_, r1_, r2_;
  bool has_res2_ = false;
  Vector tau_, qdd_, wrench_, tau2_, qdd2_, wrench2_, full_, tau_paper_;
  int retries_ = 0;
  bool replanned_ = false, fell_back_ = false;
  double base_residual_ = 0.0, coupling_residual_ = 0.0, assembly_diff_ = 0.0;
  double coupling_violation_ = 0.0, wrench_residual_ = 0.0;
  Vector cw_f_;  // Cw f (wrench_violation)
  std::string message_, failed_level_, failed_reason_;
  bool level_failed_ = false;
  double reduced_time_ = 0.0, lqp1_time_ = 0.0, lqp2_time_ = 0.0, fallback_time_ = 0.0;
  double solver_seconds_ = 0.0;
};

}  // namespace wbcbench
