#include "controllers/rc_lqp.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace wbcbench {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// PREVIEW_DAMPING and PREVIEW_RANK_TOL of the reference
constexpr double kPreviewDamping = 1e-8;
constexpr double kPreviewRankTol = 1e-6;

// A no-copy view of an index list for Eigen's indexed views.
Eigen::Map<const Eigen::ArrayXi> indices(const std::vector<int>& idx) {
  return {idx.data(), static_cast<Eigen::Index>(idx.size())};
}

// The i-th level of `levels`, made when missing (its buffers are kept from tick to tick).
PriorityLevel& level_at(std::vector<PriorityLevel>& levels, int i) {
  if (static_cast<int>(levels.size()) <= i) levels.resize(i + 1);
  return levels[i];
}

// A level with no inequalities over nx variables.
void no_inequalities(PriorityLevel& lv, int nx) {
  lv.C.resize(0, nx);
  lv.l.resize(0);
  lv.u.resize(0);
  lv.hard_if_feasible = false;
}

// Python's format(x, ".3g")
std::string g3(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", x);
  return buf;
}

double max_abs(const Eigen::Ref<const Vector>& x) {
  return x.size() ? x.cwiseAbs().maxCoeff() : 0.0;
}

}  // namespace

RcLqpTick::RcLqpTick(const std::string& model, const std::vector<std::string>& task_frames,
                     const std::vector<std::string>& contact_frames,
                     const std::vector<SplitSpec>& stances)
    : Tick(model, task_frames, contact_frames), fallback_(kPoolFallback, "fallback.") {
  // the reduced model reads M⁻¹: RobotDynamics computes it by default
  if (stances.empty() || stances.front().contact_frames != contact_frames)
    throw std::invalid_argument("rc_lqp: the first stance must hold every contact frame");
  for (const SplitSpec& split : stances) add_stance(split);
  reduced_ = stances_.front().get();
  for (int pool = 0; pool < kPoolFallback; ++pool)
    hierarchies_.push_back(std::make_unique<Hierarchy>(pool));
  levels_.resize(kPoolFallback);
}

void RcLqpTick::add_stance(const SplitSpec& split) {
  // the stance's contacts: its frames' indices, increasing (select_contacts checks the order)
  std::vector<int> active;
  for (const std::string& frame : split.contact_frames) {
    const auto it = std::find(contact_frames_.begin(), contact_frames_.end(), frame);
    if (it == contact_frames_.end())
      throw std::invalid_argument("rc_lqp: the stance's contact frame '" + frame +
                                  "' is not a contact frame of the tick");
    active.push_back(static_cast<int>(it - contact_frames_.begin()));
  }
  for (const auto& stance : stances_)
    if (stance->active_contacts() == active) return;
  // the reduced model is built on the dynamics holding the stance's contacts (its buffers are
  // sized for them); the held set is restored, and the next update() fills its buffers again
  const std::vector<int> held = dyn_.active_contacts();
  dyn_.select_contacts(active);
  try {
    stances_.push_back(std::make_unique<ReducedDynamics>(dyn_, split));
  } catch (...) {
    dyn_.select_contacts(held);
    throw;
  }
  dyn_.select_contacts(held);
}

bool RcLqpTick::select_contacts(const std::vector<int>& active) {
  ReducedDynamics* stance = nullptr;
  for (const auto& s : stances_)
    if (s->active_contacts() == active) stance = s.get();
  if (stance == nullptr) {
    std::string set;
    for (int i : active) set += (set.empty() ? "" : ", ") + std::to_string(i);
    throw std::invalid_argument("rc_lqp: no chain split for the contacts [" + set +
                                "] (add_stance first)");
  }
  if (!Tick::select_contacts(active)) return false;
  reduced_ = stance;
  classified_ = false;
  return true;
}

void RcLqpTick::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                  const Eigen::Ref<const Vector>& uw) {
  store_wrench_bounds("rc_lqp", s_, lw, uw);
  const auto nw = lw.size();
  l2_.head(nw) = lw;
  u2_.head(nw) = uw;
  fallback_.set_wrench_bounds(lw, uw);
}

void RcLqpTick::configure(const LexicographicSettings& settings, const RcLqpSettings& rc) {
  s_ = settings;
  rc_ = rc;
  n_ = nv();
  k_ = k();
  nc_ = static_cast<int>(dyn_.contact_jacobian().rows());
  n_p_ = reduced_->n_plain();
  n_r_ = reduced_->n_reduced();
  n_uc_ = static_cast<int>(reduced_->unconstrained().size());
  n_g_ = n_r_ - n_p_;
  nx1_ = n_r_ + nc_;
  const int nw = static_cast<int>(s_.Cw.rows());
  if (s_.tau_max.size() != k_) throw std::invalid_argument("rc_lqp: tau_max of wrong size");
  if (s_.Cw.cols() != nc_ || s_.lw.size() != nw || s_.uw.size() != nw)
    throw std::invalid_argument("rc_lqp: wrench constraints of wrong size");
  if (s_.priorities.size() != s_.groups.size())
    throw std::invalid_argument("rc_lqp: one priority per task group");
  if (s_.weights.empty()) throw std::invalid_argument("rc_lqp: weights must not be empty");
  if (n_p_ < 6) throw std::invalid_argument("rc_lqp: the plain coordinates must hold the base");
  fallback_.configure(settings, n_, nc_, static_cast<int>(dyn_.constraint_jacobian().rows()));

  plain_ = reduced_->split().plain;
  uc_ = reduced_->unconstrained();
  act_plain_.assign(plain_.begin() + 6, plain_.end());
  for (int& j : act_plain_) j -= 6;
  act_uc_ = uc_;
  for (int& j : act_uc_) j -= 6;
  tau_max_p_ = s_.tau_max(indices(act_plain_));
  tau_max_uc_ = s_.tau_max(indices(act_uc_));

  // LQP 1's priority 1 (hard): the Newton–Euler rows of eq. (14) and the constraint chain's
  // torque limits; the contacts level's inequalities: the wrench cone and the q̈ limits
  const int n_act = n_p_ - 6;
  hard1_.zero(6, n_act, nx1_);
  hard1r_ = hard1_;
  hard1r_.A.setZero(6 + n_g_, nx1_);
  hard1r_.b.setZero(6 + n_g_);
  hard2_.zero(0, 0, n_uc_);
  C2_.setZero(nw + n_act, nx1_);
  C2_.block(0, n_r_, nw, nc_) = s_.Cw;
  C2_.block(nw, 6, n_act, n_act).setIdentity();
  l2_.resize(nw + n_act);
  u2_.resize(nw + n_act);
  l2_ << s_.lw, Vector::Constant(n_act, -s_.qdd_limit);
  u2_ << s_.uw, Vector::Constant(n_act, s_.qdd_limit);
  G1_.setZero(n_act, nx1_);
  gamma1_.setZero(n_act);
  nl_.setZero(n_r_);
  llt_r_ = Eigen::LLT<Matrix>(n_r_);
  D_.setZero(n_g_, n_p_);
  d0_.setZero(n_g_);
  gamma2_.setZero(n_uc_);
  cross_.setZero(n_uc_);
  tau_.setZero(k_);
  qdd_.setZero(n_);
  wrench_.setZero(nc_);
  full_.setZero(n_);
  tau_paper_.setZero(k_);
  classified_ = false;
  rows1_.assign(s_.groups.size(), {});
  rows2_.assign(s_.groups.size(), {});
  chain_priority_ = 0;
  // the scratch every tick fills, at its sizes
  const auto rows = tasks_.J().rows();
  J_.setZero(rows, n_);
  Jp_.setZero(rows, n_p_);
  v1_.setZero(rows);
  v2_.setZero(rows);
  M_up_.setZero(n_uc_, n_p_);
  x1_.setZero(nx1_);
  reached_.setZero(n_g_);
  w_.setZero(n_g_);
  tau_p_.setZero(n_act);
  qdd_uc_.setZero(n_uc_);
  uc_work_.setZero(n_uc_);
  g_work_.setZero(n_g_);
  pu_.setZero(n_uc_, 1 + n_p_);
  cw_f_.setZero(nw);
}

int RcLqpTick::handles(int pool) const {
  if (pool == kPoolFallback) return fallback_.handles();
  if (pool < 0 || pool > kPoolFallback) throw std::out_of_range("rc_lqp: no such pool");
  // at most: contacts (or LQP 2's limits), every priority, the preview, the coupling, the
  // energy; twice (the slack QPs' handles)
  return 2 * (static_cast<int>(s_.groups.size()) + 4);
}

const QpBuffers& RcLqpTick::slot(int pool, int i) const {
  if (pool == kPoolFallback) return fallback_.hierarchy().slot(i);
  return hierarchies_.at(pool)->slot(i);
}

// RcLqp.row_split's result, decided in Python at set-up (the test of J N_r = 0 runs at two
// postures there): per task, its rows that go to LQP 1; the others go to LQP 2
void RcLqpTick::set_row_split(const std::vector<std::vector<int>>& lqp1_rows) {
  if (static_cast<int>(lqp1_rows.size()) != tasks_.size())
    throw std::invalid_argument("rc_lqp: the row split needs one row list per task");
  chain_priority_ = 0;
  for (size_t g = 0; g < s_.groups.size(); ++g) {
    rows1_[g].clear();
    rows2_[g].clear();
    for (int task : s_.groups[g]) {
      const int o = tasks_.offset(task), m = tasks_.dim(task);
      const std::vector<int>& mine = lqp1_rows[task];
      for (int r = 0; r < m; ++r) {
        const bool in1 = std::find(mine.begin(), mine.end(), r) != mine.end();
        (in1 ? rows1_[g] : rows2_[g]).push_back(o + r);
      }
    }
    if (!rows2_[g].empty() && chain_priority_ == 0) chain_priority_ = s_.priorities[g];
  }
  preview_groups_.clear();
  for (size_t g = 0; g < rows2_.size(); ++g)
    if (!rows2_[g].empty()) preview_groups_.push_back(static_cast<int>(g));
  pw_.resize(preview_groups_.size());
  classified_ = true;
}

// RcLqp.preview: the chains' centroidal accelerations their tasks ask for, d = D q̈_p + d0;
// priority after priority by damped least squares in the coordinates u = Lᵀ q̈_uc, in the
// null space of the priorities above; u = u0 + B q̈_p carried as one matrix [u0 B]
void RcLqpTick::preview() {
  const Matrix& Lt = reduced_->M_uc_factor();
  const auto plain = indices(plain_);
  const auto uc = indices(uc_);
  Matrix& u = pu_;
  u.setZero();
  const Matrix* Z = nullptr;  // orthonormal basis of what is left free (in u); null: all
  for (size_t i = 0; i < preview_groups_.size(); ++i) {
    PreviewWork& pw = pw_[i];
    const bool last = i + 1 == preview_groups_.size();
    const auto r = indices(rows2_[preview_groups_[i]]);
    pw.J = tasks_.J()(r, Eigen::all);
    // J_uc L⁻ᵀ (= J_uc Lt⁻¹)
    pw.Ju = pw.J(Eigen::all, uc);
    Lt.triangularView<Eigen::Upper>().solveInPlace<Eigen::OnTheRight>(pw.Ju);
    // the rows' residual at u: [b − J_uc q̈_uc(u0)] − [J_p + J_uc L⁻ᵀ B] q̈_p
    pw.rhs.resize(pw.J.rows(), 1 + n_p_);
    pw.rhs.col(0) = tasks_.acc_ref()(r) - tasks_.drift()(r);
    pw.rhs.rightCols(n_p_) = -pw.J(Eigen::all, plain);
    pw.rhs.noalias() -= pw.Ju * u;
    if (Z != nullptr) pw.K.noalias() = pw.Ju * *Z;
    const Matrix& K = Z == nullptr ? pw.Ju : pw.K;
    const unsigned int vs = last ? Eigen::ComputeThinV : Eigen::ComputeFullV;
    pw.svd.compute(K, Eigen::ComputeThinU | vs);
    const Vector& sv = pw.svd.singularValues();
    int rank = 0;
    if (sv.size() && sv(0) > 0.0)
      rank = static_cast<int>((sv.array() > kPreviewRankTol * sv(0)).count());
    if (rank) {
      pw.s_r = sv.head(rank);
      pw.gain = pw.s_r.array() / (pw.s_r.array().square() + kPreviewDamping * sv(0) * sv(0));
      pw.coef.noalias() = pw.svd.matrixU().leftCols(rank).transpose() * pw.rhs;
      pw.coef = pw.gain.asDiagonal() * pw.coef;
      if (Z == nullptr) {
        u.noalias() += pw.svd.matrixV().leftCols(rank) * pw.coef;
      } else {
        pw.Vr.noalias() = *Z * pw.svd.matrixV().leftCols(rank);
        u.noalias() += pw.Vr * pw.coef;
      }
    }
    if (last) break;
    const int free = static_cast<int>(K.cols()) - rank;
    if (Z == nullptr)
      pw.Z = pw.svd.matrixV().rightCols(free);
    else
      pw.Z.noalias() = *Z * pw.svd.matrixV().rightCols(free);
    Z = &pw.Z;
    if (Z->cols() == 0) break;
  }
  // q̈_uc = L⁻ᵀ u; d = J_G q̈_uc + J̇_G q̇
  Lt.triangularView<Eigen::Upper>().solveInPlace(u);
  D_.noalias() = reduced_->J_G() * u.rightCols(n_p_);
  d0_ = reduced_->dJG_v();
  d0_.noalias() += reduced_->J_G() * u.col(0);
}

// LQP 1's hard constraints and torque map Γ_p = G₁ x₁ + γ₁ at this tick (lqp1_levels' first
// part), and M_r's Cholesky factor for its energy
void RcLqpTick::prepare_lqp1() {
  const Matrix& M_r = reduced_->M_r();
  const Matrix& J_cr = reduced_->J_cr();
  const int n_act = n_p_ - 6;
  nl_ = reduced_->b_r() + reduced_->g_r();
  G1_.leftCols(n_r_) = M_r.middleRows(6, n_act);
  G1_.rightCols(nc_) = -J_cr.middleCols(6, n_act).transpose();
  gamma1_ = nl_.segment(6, n_act);
  hard1_.A.leftCols(n_r_) = M_r.topRows(6);
  hard1_.A.rightCols(nc_) = -J_cr.leftCols(6).transpose();
  hard1_.b = -nl_.head(6);
  hard1_.C = G1_;
  hard1_.l = -tau_max_p_ - gamma1_;
  hard1_.u = tau_max_p_ - gamma1_;
  llt_r_.compute(M_r);
  if (llt_r_.info() != Eigen::Success)
    throw std::runtime_error("rc_lqp: M_r is not positive definite");
}

// RcLqp.lqp1_levels: contacts, the task rows J N_r = 0 per priority (eq. 22), the preview
// level right after the chains' highest task priority; returns the level count
int RcLqpTick::lqp1_levels(std::vector<PriorityLevel>& levels, bool with_preview) {
  int count = 0;
  PriorityLevel& contacts = level_at(levels, count++);
  contacts.name = "lqp1.contacts";
  if (dyn_.constraint_map().size() == 0) {
    contacts.A.setZero(nc_, nx1_);
    contacts.A.leftCols(n_r_) = reduced_->J_cr();
    contacts.b = -dyn_.contact_drift();
  } else {  // a point set's independent rows
    const Matrix& T = dyn_.constraint_map();
    contacts.A.setZero(T.rows(), nx1_);
    contacts.A.leftCols(n_r_).noalias() = T * reduced_->J_cr();
    contacts.b = -dyn_.constraint_drift();
  }
  contacts.C = C2_;
  contacts.l = l2_;
  contacts.u = u2_;
  contacts.hard_if_feasible = true;
  bool pending = with_preview;
  for (size_t g = 0; g < s_.groups.size(); ++g) {
    const int p = s_.priorities[g];
    if (pending && p > chain_priority_) {
      preview_level(level_at(levels, count++));
      pending = false;
    }
    const std::vector<int>& rows = rows1_[g];
    if (rows.empty()) continue;
    const auto r = indices(rows);
    const int m = static_cast<int>(rows.size());
    PriorityLevel& lv = level_at(levels, count++);
    lv.name = "lqp1.p" + std::to_string(p);
    J_.topRows(m) = tasks_.J()(r, Eigen::all);
    v1_.head(m) = tasks_.drift()(r);
    lv.A.setZero(m, nx1_);
    reduced_->task(J_.topRows(m), v1_.head(m), lv.A.leftCols(n_r_), v2_.head(m));
    lv.b = tasks_.acc_ref()(r) - v2_.head(m);
    no_inequalities(lv, nx1_);
  }
  if (pending) preview_level(level_at(levels, count++));
  return count;
}

// RcLqp._preview_level: q̈_r,G = D q̈_p + d0
void RcLqpTick::preview_level(PriorityLevel& lv) const {
  lv.name = "lqp1.preview";
  lv.A.setZero(n_g_, nx1_);
  lv.A.leftCols(n_p_) = -D_;
  lv.A.block(0, n_p_, n_g_, n_g_).diagonal().array() += 1.0;
  lv.b = d0_;
  no_inequalities(lv, nx1_);
}

HierarchyOptions RcLqpTick::options(int count) const {
  HierarchyOptions o;
  o.strategy = s_.strategy;
  o.prox = s_.prox;
  o.accept_tol = s_.accept_tol;
  o.merge_finals = true;
  o.slack_free_first = true;
  o.handles = 2 * (count + 1);
  return o;
}

// RcLqp.solve_lqp1: the levels weighted, the energy q̈_rᵀ M_r q̈_r + reg ‖f‖² (eq. 28) in the
// last level's cost, aimed at the preview when `target`
const HierarchyResult& RcLqpTick::solve_lqp1(int pool, const HardConstraints& hard,
                                             std::vector<PriorityLevel>& levels, int count,
                                             bool target, LevelSolver& solver) {
  for (int i = 0; i < count; ++i)
    levels[i].weight = s_.weights[std::min<size_t>(i, s_.weights.size() - 1)];
  PriorityLevel& f = level_at(levels, count);
  levels.resize(count + 1);
  f.name = "lqp1.energy";
  f.A.setZero(nx1_, nx1_);
  f.A.topLeftCorner(n_r_, n_r_) = llt_r_.matrixU();
  f.A.bottomRightCorner(nc_, nc_).diagonal().setConstant(std::sqrt(s_.wrench_regularization));
  f.b.setZero(nx1_);
  if (target) {
    // ‖Lᵀ (q̈_r − d)‖², d zero but for the chains' centroidal rows, where it is D q̈_p + d0
    const auto F_G = f.A.block(0, n_p_, n_r_, n_g_);
    f.A.topLeftCorner(n_r_, n_p_).noalias() -= F_G * D_;
    f.b.head(n_r_).noalias() = F_G * d0_;
  }
  no_inequalities(f, nx1_);
  f.weight = s_.final_weight;
  Hierarchy& h = *hierarchies_[pool];
  const HierarchyResult& result = h.solve(hard, levels, 1, options(count), solver);
  solver_seconds_ += h.solver_seconds();
  return result;
}

// RcLqp.lqp2_levels: eq. (30) with the chains' torque and q̈ limits (or the limits first and
// eq. 30 last), then the task rows LQP 1 does not handle with its base and constraint-chain
// accelerations on the right-hand side; returns the level count
int RcLqpTick::lqp2_levels(std::vector<PriorityLevel>& levels, const Vector& x1,
                           bool with_tasks, bool coupling_last) {
  const auto plain = indices(plain_);
  const auto uc = indices(uc_);
  const auto qdd_plain = x1.head(n_p_);
  if (rc_.assembly == Assembly::kExact) {
    gamma2_.noalias() = M_up_ * qdd_plain;
    gamma2_ += dyn_.h()(uc);
  } else {
    gamma2_ = reduced_->b_uc() + reduced_->g_uc();
  }
  int count = 0;
  PriorityLevel& top = level_at(levels, count++);
  top.name = coupling_last ? "lqp2.limits" : "lqp2.coupling";
  if (coupling_last) {
    top.A.resize(0, n_uc_);
    top.b.resize(0);
  } else {
    top.A = reduced_->J_G();
    top.b = x1.segment(n_p_, n_g_) - reduced_->dJG_v();
  }
  top.C.resize(2 * n_uc_, n_uc_);
  top.C.topRows(n_uc_) = reduced_->M_uc();
  top.C.bottomRows(n_uc_).setIdentity();
  top.l.resize(2 * n_uc_);
  top.u.resize(2 * n_uc_);
  top.l << -tau_max_uc_ - gamma2_, Vector::Constant(n_uc_, -s_.qdd_limit);
  top.u << tau_max_uc_ - gamma2_, Vector::Constant(n_uc_, s_.qdd_limit);
  top.hard_if_feasible = true;
  if (with_tasks) {
    for (size_t g = 0; g < s_.groups.size(); ++g) {
      const std::vector<int>& rows = rows2_[g];
      if (rows.empty()) continue;
      const auto r = indices(rows);
      const int m = static_cast<int>(rows.size());
      PriorityLevel& lv = level_at(levels, count++);
      lv.name = "lqp2.p" + std::to_string(s_.priorities[g]);
      J_.topRows(m) = tasks_.J()(r, Eigen::all);
      lv.A = J_.topRows(m)(Eigen::all, uc);
      // base-relative reference: LQP 1's base and constraint-chain accelerations are known
      lv.b = tasks_.acc_ref()(r) - tasks_.drift()(r);
      Jp_.topRows(m) = J_.topRows(m)(Eigen::all, plain);
      lv.b.noalias() -= Jp_.topRows(m) * qdd_plain;
      no_inequalities(lv, n_uc_);
    }
  }
  if (coupling_last) {
    PriorityLevel& lv = level_at(levels, count++);
    lv.name = "lqp2.coupling";
    lv.A = reduced_->J_G();
    lv.b = x1.segment(n_p_, n_g_) - reduced_->dJG_v();
    no_inequalities(lv, n_uc_);
  }
  return count;
}

// RcLqp.solve_lqp2: the energy q̈_ucᵀ M_uc q̈_uc (eq. 29), or the whole robot's q̈ᵀ M q̈ with
// LQP 1's q̈ fixed (= ‖Lᵀ q̈_uc − f‖² + const, L f = −M_up q̈_p), in the last level's cost
const HierarchyResult& RcLqpTick::solve_lqp2(int pool, std::vector<PriorityLevel>& levels,
                                             int count, const Vector& x1, LevelSolver& solver) {
  for (int i = 0; i < count; ++i)
    levels[i].weight = s_.weights[std::min<size_t>(i, s_.weights.size() - 1)];
  PriorityLevel& f = level_at(levels, count);
  levels.resize(count + 1);
  const Matrix& Lt = reduced_->M_uc_factor();
  f.name = "lqp2.energy";
  f.A = Lt;
  if (rc_.lqp2_energy == Lqp2Energy::kWhole) {
    cross_.noalias() = M_up_ * x1.head(n_p_);
    f.b = cross_;
    Lt.triangularView<Eigen::Upper>().transpose().solveInPlace(f.b);
    f.b *= -1.0;
  } else {
    f.b.setZero(n_uc_);
  }
  no_inequalities(f, n_uc_);
  f.weight = s_.final_weight;
  Hierarchy& h = *hierarchies_[pool];
  const HierarchyResult& result = h.solve(hard2_, levels, 1, options(count), solver);
  solver_seconds_ += h.solver_seconds();
  return result;
}

bool RcLqpTick::fail(const std::string& prefix, const HierarchyResult& result) {
  message_ = prefix;
  level_failed_ = true;
  failed_level_ = result.failed_level;
  failed_reason_ = result.message;
  return false;
}

// RcLqp._plan: LQP 1 then LQP 2, with coupling_priority's re-solve
bool RcLqpTick::plan(bool level, bool target, LevelSolver& solver) {
  auto t1 = Clock::now();
  int count = lqp1_levels(levels_[kPoolLqp1], level);
  res1_ = solve_lqp1(kPoolLqp1, hard1_, levels_[kPoolLqp1], count, target, solver);
  lqp1_time_ += seconds_since(t1);
  if (!res1_.ok) return fail("LQP 1: ", res1_);
  if (n_uc_ == 0) return true;
  auto t2 = Clock::now();
  count = lqp2_levels(levels_[kPoolLqp2], res1_.x, true, rc_.coupling_priority);
  res2_ = solve_lqp2(kPoolLqp2, levels_[kPoolLqp2], count, res1_.x, solver);
  has_res2_ = true;
  lqp2_time_ += seconds_since(t2);
  if (res2_.ok && rc_.coupling_priority) {
    w_ = res2_.levels.at(count - 1).w;  // eq. (30)'s violation (the last level)
    coupling_violation_ = w_.norm();
    if (w_.norm() > rc_.coupling_tol) {
      // LQP 1 again, the centroidal acceleration LQP 2 reached as an extra priority
      t1 = Clock::now();
      reached_ = res1_.x.segment(n_p_, n_g_) + w_;
      std::vector<PriorityLevel>& levels = levels_[kPoolLqp1Coupling];
      count = lqp1_levels(levels, level);
      PriorityLevel& lv = level_at(levels, count++);
      lv.name = "lqp1.coupling";
      lv.A.setZero(n_g_, nx1_);
      lv.A.block(0, n_p_, n_g_, n_g_).setIdentity();
      lv.b = reached_;
      no_inequalities(lv, nx1_);
      res1_ = solve_lqp1(kPoolLqp1Coupling, hard1_, levels, count, target, solver);
      lqp1_time_ += seconds_since(t1);
      if (!res1_.ok) {
        has_res2_ = false;
        return fail("LQP 1 (coupling): ", res1_);
      }
      t2 = Clock::now();
      count = lqp2_levels(levels_[kPoolLqp2Coupling], res1_.x, true, false);
      res2_ = solve_lqp2(kPoolLqp2Coupling, levels_[kPoolLqp2Coupling], count, res1_.x, solver);
      lqp2_time_ += seconds_since(t2);
    }
  }
  if (!res2_.ok) return fail("LQP 2: ", res2_);
  return true;
}

// RcLqp._replan: the centroidal acceleration the chains can reach within their limits becomes
// a hard constraint of LQP 1, then LQP 2 again; false when a hierarchy failed
bool RcLqpTick::replan(LevelSolver& solver) {
  if (n_uc_ == 0) return false;
  x1_ = res1_.x;
  const Vector& x1 = x1_;
  auto t2 = Clock::now();
  int count = lqp2_levels(levels_[kPoolLqp2Reach], x1, false, true);
  const HierarchyResult& reach =
      solve_lqp2(kPoolLqp2Reach, levels_[kPoolLqp2Reach], count, x1, solver);
  lqp2_time_ += seconds_since(t2);
  if (!reach.ok) return false;
  const LevelResult* coupling = nullptr;
  for (const LevelResult& lv : reach.levels)
    if (lv.name == "lqp2.coupling") coupling = &lv;
  if (coupling == nullptr) throw std::logic_error("rc_lqp: the re-plan has no coupling level");
  auto t1 = Clock::now();
  hard1r_.A.topRows(6) = hard1_.A;
  hard1r_.A.bottomRows(n_g_).setZero();
  hard1r_.A.block(6, n_p_, n_g_, n_g_).setIdentity();
  hard1r_.b.head(6) = hard1_.b;
  hard1r_.b.tail(n_g_) = x1.segment(n_p_, n_g_) + coupling->w;
  hard1r_.C = hard1_.C;
  hard1r_.l = hard1_.l;
  hard1r_.u = hard1_.u;
  count = lqp1_levels(levels_[kPoolLqp1Replan], false);
  r1_ = solve_lqp1(kPoolLqp1Replan, hard1r_, levels_[kPoolLqp1Replan], count, false, solver);
  lqp1_time_ += seconds_since(t1);
  if (!r1_.ok) return false;
  t2 = Clock::now();
  count = lqp2_levels(levels_[kPoolLqp2Replan], r1_.x, true, false);
  r2_ = solve_lqp2(kPoolLqp2Replan, levels_[kPoolLqp2Replan], count, r1_.x, solver);
  lqp2_time_ += seconds_since(t2);
  return r2_.ok;
}

// rc_lqp.wrench_violation
double RcLqpTick::wrench_violation(const Vector& f) {
  if (s_.Cw.rows() == 0) return 0.0;
  cw_f_.noalias() = s_.Cw * f;
  return std::max({0.0, (s_.lw - cw_f_).maxCoeff(), (cw_f_ - s_.uw).maxCoeff()});
}

// RcLqp._assemble: (q̈, f, Γ) of the combined solution and why the step must not be trusted
// ("" if it may)
std::string RcLqpTick::assemble(const Vector& x1, const Vector* x2, Vector& qdd, Vector& f,
                                Vector& tau, Diagnostics& d) {
  const auto plain = indices(plain_);
  const auto uc = indices(uc_);
  const Matrix& M = dyn_.M();
  const Vector& h = dyn_.h();
  const Matrix& Jc = dyn_.contact_jacobian();
  qdd.setZero(n_);
  qdd(plain) = x1.head(n_p_);
  f = x1.tail(nc_);
  if (x2 != nullptr) qdd(uc) = *x2;
  qdd_uc_ = qdd(uc);
  // the full inverse dynamics at (q̈, f): actuated rows for Γ, base rows as a check
  full_ = h;
  full_.noalias() += M * qdd;
  full_.noalias() -= Jc.transpose() * f;
  tau = full_.tail(k_);
  d.assembly_diff = kNaN;
  if (rc_.assembly == Assembly::kPaper || rc_.diagnostics) {
    tau_p_.noalias() = G1_ * x1;
    tau_p_ += nl_.segment(6, n_p_ - 6);
    tau_paper_(indices(act_plain_)) = tau_p_;
    if (n_uc_) {
      uc_work_ = reduced_->b_uc() + reduced_->g_uc();
      uc_work_.noalias() += reduced_->M_uc() * qdd_uc_;
      tau_paper_(indices(act_uc_)) = uc_work_;
    }
    d.assembly_diff = (tau - tau_paper_).cwiseAbs().maxCoeff();
    if (rc_.assembly == Assembly::kPaper) tau = tau_paper_;
  }
  const double tol = rc_.coupling_tol;
  d.base_residual = max_abs(full_.head(6));
  d.coupling_residual = kNaN;
  std::string why;
  if (n_uc_) {
    g_work_ = reduced_->dJG_v() - x1.segment(n_p_, n_g_);
    g_work_.noalias() += reduced_->J_G() * qdd_uc_;
    d.coupling_residual = max_abs(g_work_);
    if (d.coupling_residual > tol)
      why = "eq. (30) not met (residual " + g3(d.coupling_residual) + ")";
  }
  if (why.empty() && rc_.assembly == Assembly::kExact) {
    const double scale = std::max(1.0, max_abs(h.head(6)));
    if (d.base_residual > tol * scale)
      why = "floating-base rows not met (" + g3(d.base_residual) + " N)";
  }
  const double excess = (tau.cwiseAbs() - s_.tau_max * (1.0 + tol)).maxCoeff();
  if (why.empty() && excess > tol) why = "torque limit exceeded by " + g3(excess) + " N·m";
  d.wrench_residual = wrench_violation(f);
  if (why.empty() && d.wrench_residual > rc_.wrench_tol * std::max(1.0, max_abs(f)))
    why = "wrench inequalities broken by " + g3(d.wrench_residual);
  return why;
}

// RcLqp.step
bool RcLqpTick::run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                    double t, LevelSolver& solver) {
  const auto t0 = Clock::now();
  evaluate(q, v, t);
  message_.clear();
  failed_level_.clear();
  failed_reason_.clear();
  level_failed_ = false;
  res1_ = HierarchyResult();
  res2_ = HierarchyResult();
  has_res2_ = false;
  retries_ = 0;
  replanned_ = fell_back_ = false;
  base_residual_ = coupling_residual_ = assembly_diff_ = coupling_violation_ = kNaN;
  wrench_residual_ = kNaN;
  reduced_time_ = lqp1_time_ = lqp2_time_ = fallback_time_ = 0.0;
  solver_seconds_ = 0.0;
  const auto done = [&](bool ok) {
    times_.build = seconds_since(t0) - times_.dynamics - solver_seconds_;
    return ok;
  };
  if (!dynamics_finite(dyn_, tasks_)) {
    level_failed_ = true;  // (no level: the caller says the data hold a NaN)
    return done(false);
  }
  reduced_time_ = reduced_->compute(rc_.assembly == Assembly::kPaper || rc_.diagnostics);
  if (!classified_) throw std::logic_error("rc_lqp: run before set_row_split");
  if (n_uc_) M_up_ = dyn_.M()(indices(uc_), indices(plain_));
  const auto tp = Clock::now();
  prepare_lqp1();  // (the reference builds these inside LQP 1's formulation)
  lqp1_time_ += seconds_since(tp);

  // the chains' centroidal accelerations: a level of LQP 1 (priority) or its energy's target
  const bool with_preview = rc_.centroid_preview != CentroidPreview::kOff && n_uc_ > 0;
  if (with_preview) preview();
  const bool level = with_preview && rc_.centroid_preview == CentroidPreview::kPriority;
  const bool target = with_preview && rc_.centroid_preview == CentroidPreview::kEnergy;
  if (!plan(level, target, solver)) return done(false);
  Diagnostics diag;
  std::string why = assemble(res1_.x, has_res2_ ? &res2_.x : nullptr, qdd_, wrench_, tau_, diag);
  retries_ = res1_.retries + (has_res2_ ? res2_.retries : 0);
  if (!why.empty() && rc_.infeasible_coupling == InfeasibleCoupling::kReplan) {
    // eq. (30) within the chains' limits is infeasible for what LQP 1 asked: re-plan
    replanned_ = true;
    if (replan(solver)) {
      Diagnostics retry;
      if (assemble(r1_.x, &r2_.x, qdd2_, wrench2_, tau2_, retry).empty()) {
        qdd_.swap(qdd2_);
        wrench_.swap(wrench2_);
        tau_.swap(tau2_);
        why.clear();
        diag = retry;
      }
    }
    if (!why.empty()) {
      // still not met: the whole tick by the full-model LQP (same priorities)
      const auto tf = Clock::now();
      const bool ok = fallback_.solve(dyn_, tasks_, solver);
      solver_seconds_ += fallback_.solver_seconds();
      fallback_time_ = seconds_since(tf);
      if (!ok) {
        message_ = why + "; re-planning did not meet it and the full-model LQP failed: ";
        level_failed_ = true;
        failed_level_ = fallback_.result().failed_level;
        failed_reason_ = fallback_.result().message;
        return done(false);
      }
      fell_back_ = true;
      why.clear();
      qdd_ = fallback_.qdd();
      wrench_ = fallback_.wrench();
      tau_ = fallback_.tau();
      // the residuals of the solution applied (the full model has no eq. 30)
      Vector6 base = dyn_.h().head(6);
      base.noalias() += dyn_.M().topRows(6) * qdd_;
      base.noalias() -= dyn_.contact_jacobian().leftCols(6).transpose() * wrench_;
      diag.base_residual = max_abs(base);
      diag.coupling_residual = kNaN;
      diag.wrench_residual = wrench_violation(wrench_);
    }
  }
  if (!why.empty()) {
    message_ = why + ": eq. (30) cannot be met within the chains' torque and q̈ limits";
    return done(false);
  }
  base_residual_ = diag.base_residual;
  wrench_residual_ = diag.wrench_residual;
  coupling_residual_ = diag.coupling_residual;
  assembly_diff_ = diag.assembly_diff;
  return done(true);
}

}  // namespace wbcbench
