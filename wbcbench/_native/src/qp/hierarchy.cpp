#include "qp/hierarchy.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>

namespace wbcbench {

namespace {

constexpr double kRankTol = 1e-10;
// At level i (0-based) inequality bounds are widened by (i kFeasTol + carried) (1 + |bound|):
// see FEAS_TOL in wbcbench/qp/hierarchy.py
constexpr double kFeasTol = 1e-9;

using Index = Eigen::Index;
using ConstRef = const Eigen::Ref<const Vector>&;

// Ranks count |R_ii| > tol · max(1, |R_00|), as the reference does.
int qr_rank(const Eigen::ColPivHouseholderQR<Matrix>& qr, double tol) {
  const Index k = std::min(qr.rows(), qr.cols());
  if (k == 0) return 0;
  const auto d = qr.matrixQR().diagonal().cwiseAbs();
  const double threshold = tol * std::max(1.0, d(0));
  return static_cast<int>((d.array() > threshold).count());
}

// dst ← Q dst, Q = H₀ ⋯ H_{k−1} the QR's reflectors (those householderQ() holds), applied one
// by one with the caller's workspace (Eigen's blocked application allocates). With
// `identity_from` ≥ 0, dst holds the identity's columns from that one on (Q's columns are
// formed): H_k then changes only the rows from k of the columns from k − identity_from.
template <typename Dest>
void apply_q(const Eigen::ColPivHouseholderQR<Matrix>& qr, Dest&& dst, Vector& work,
             Index identity_from = -1) {
  const Index n = qr.rows(), cols = dst.cols();
  if (work.size() < cols) work.resize(cols);
  for (Index k = qr.hCoeffs().size() - 1; k >= 0; --k) {
    const Index c = identity_from < 0 ? 0 : std::max<Index>(0, k - identity_from);
    if (c >= cols) continue;
    dst.block(k, c, n - k, cols - c)
        .applyHouseholderOnTheLeft(qr.matrixQR().col(k).tail(n - k - 1), qr.hCoeffs()(k),
                                   work.data());
  }
}

// x ← Q x for a vector: the reflectors H_k = I − τ_k v_k v_kᵀ (v_k = (1, essential part))
// applied in turn, written out (Eigen's application to a vector's block makes a temporary)
void apply_q(const Eigen::ColPivHouseholderQR<Matrix>& qr, Vector& x) {
  const Index n = qr.rows();
  for (Index k = qr.hCoeffs().size() - 1; k >= 0; --k) {
    const auto essential = qr.matrixQR().col(k).tail(n - k - 1);
    auto tail = x.tail(n - k - 1);
    const double w = qr.hCoeffs()(k) * (x(k) + essential.dot(tail));
    x(k) -= w;
    tail -= w * essential;
  }
}

// the top-left (rows, cols) block of buf, grown (never shrunk) to hold it
auto sized(Matrix& buf, Index rows, Index cols) {
  if (buf.rows() < rows || buf.cols() < cols)
    buf.resize(std::max(buf.rows(), rows), std::max(buf.cols(), cols));
  return buf.topLeftCorner(rows, cols);
}
auto sized(Vector& buf, Index size) {
  if (buf.size() < size) buf.resize(size);
  return buf.head(size);
}

double max_abs(ConstRef v) { return v.size() ? v.cwiseAbs().maxCoeff() : 0.0; }

void widen(const Vector& lower, const Vector& upper, double relax, Eigen::Ref<Vector> lo,
           Eigen::Ref<Vector> hi) {
  if (relax == 0.0) {
    lo = lower;
    hi = upper;
    return;
  }
  lo = lower.array() - relax * (1.0 + lower.array().abs());
  hi = upper.array() + relax * (1.0 + upper.array().abs());
}

// max over rows of how far Cx lies outside [l, u], relative to 1 + |bound| (0 inside)
double relative_violation(ConstRef Cx, const Vector& lower, const Vector& upper) {
  double worst = 0.0;
  for (Index i = 0; i < Cx.size(); ++i) {
    if (std::isfinite(lower(i)))
      worst = std::max(worst, (lower(i) - Cx(i)) / (1.0 + std::abs(lower(i))));
    if (std::isfinite(upper(i)))
      worst = std::max(worst, (Cx(i) - upper(i)) / (1.0 + std::abs(upper(i))));
  }
  return worst;
}

// how far Cx lies outside [l, u] widened by relax (1 + |bound|) (0 inside), and the rows'
// scale: the largest |Cx| and finite |bound| (mirrors wbcbench.qp.hierarchy._excess)
std::pair<double, double> excess_and_scale(ConstRef Cx, const Vector& lower, const Vector& upper,
                                           double relax) {
  double worst = 0.0, scale = 0.0;
  for (Index i = 0; i < Cx.size(); ++i) {
    if (std::isfinite(Cx(i))) scale = std::max(scale, std::abs(Cx(i)));
    if (std::isfinite(lower(i))) {
      scale = std::max(scale, std::abs(lower(i)));
      worst = std::max(worst, lower(i) - relax * (1.0 + std::abs(lower(i))) - Cx(i));
    }
    if (std::isfinite(upper(i))) {
      scale = std::max(scale, std::abs(upper(i)));
      worst = std::max(worst, Cx(i) - upper(i) - relax * (1.0 + std::abs(upper(i))));
    }
  }
  return {worst, scale};
}

// signed slack v that puts C x − v inside [l, u] with the smallest |v| (into v, sized)
void violation(ConstRef Cx, const Vector& lower, const Vector& upper, Vector& v) {
  v.resize(Cx.size());
  for (Index i = 0; i < Cx.size(); ++i)
    v(i) = Cx(i) > upper(i) ? Cx(i) - upper(i) : (Cx(i) < lower(i) ? Cx(i) - lower(i) : 0.0);
}

// the last r inequality rows of the QP have (numerically) zero multipliers
bool own_multipliers_vanish(const Vector& qp_x, const Vector& z, bool has_z, Index r) {
  if (!has_z || z.size() < r) return false;
  const double z_own = r ? z.tail(r).cwiseAbs().maxCoeff() : 0.0;
  const double z_max = z.size() ? z.cwiseAbs().maxCoeff() : 0.0;
  const double x_max = qp_x.size() ? qp_x.cwiseAbs().maxCoeff() : 0.0;
  // a multiplier at the solver's tolerance changes the level's optimum at that tolerance only
  return z_own <= 1e-6 * std::max({1.0, z_max, x_max});
}

const std::string kWeighted = "weighted";

}  // namespace

void Bases::factor(const Eigen::Ref<const Matrix>& E, bool want_R, bool want_Z, double tol) {
  const Index n = E.cols();
  empty_ = E.rows() == 0 || n == 0;
  if (empty_) {  // (an empty factorisation)
    rank_ = 0;
    if (want_R) Q1_.setZero(n, 0);
    if (want_Z) Z_.setIdentity(n, n);
    return;
  }
  qr_.compute(E.transpose());  // Eᵀ P = Q R
  rank_ = qr_rank(qr_, tol);
  // R = Q₁ᵀ, Z = Q₂: only the columns of Q asked for are formed, the reflectors applied to
  // the identity's columns
  if (want_R) {
    Q1_.setIdentity(n, rank_);
    apply_q(qr_, Q1_, work_, 0);
  }
  if (want_Z) {
    Z_.setZero(n, n - rank_);
    Z_.bottomRows(n - rank_).setIdentity();
    apply_q(qr_, Z_, work_, rank_);
  }
}

void Bases::min_norm(const Eigen::Ref<const Matrix>& E, const Eigen::Ref<const Vector>& b,
                     Vector& x) {
  const Index n = E.cols();
  if (empty_) {
    x.setZero(n);
    return;
  }
  if (rank_ == E.rows()) {
    // Pᵀ E = Rᵀ Qᵀ: x = Q₁ y with R₁ᵀ y = Pᵀ b is the minimum-norm solution
    rhs_.noalias() = qr_.colsPermutation().transpose() * b;
    x.setZero(n);
    x.head(rank_) = rhs_.head(rank_);
    qr_.matrixQR()
        .topLeftCorner(rank_, rank_)
        .triangularView<Eigen::Upper>()
        .transpose()
        .solveInPlace(x.head(rank_));
    apply_q(qr_, x);
  } else {
    cod_.compute(E);
    x = cod_.solve(b);
  }
}

void row_space_and_null_space(const Matrix& E, Matrix* R, Matrix* Z, double tol) {
  Bases bases;
  bases.factor(E, R != nullptr, Z != nullptr, tol);
  if (R) *R = bases.Q1().transpose();
  if (Z) *Z = bases.Z();
}

void row_space_and_null_space(const Matrix& E, Matrix& R, Matrix& Z, double tol) {
  row_space_and_null_space(E, &R, &Z, tol);
}

QpBuffers& Hierarchy::prepare(int handle, int kind, int n, int n_eq, int n_in, bool box) {
  int found = -1;
  for (size_t i = 0; i < slots_.size() && found < 0; ++i) {
    const Slot& s = *slots_[i];
    if (s.handle == handle && s.kind == kind && s.n == n && s.n_eq == n_eq && s.n_in == n_in &&
        s.box == box)
      found = static_cast<int>(i);
  }
  reshaped_ = found < 0;
  if (reshaped_) {
    found = static_cast<int>(slots_.size());
    slots_.push_back(std::make_unique<Slot>());
    Slot& s = *slots_.back();
    s.handle = handle;
    s.kind = kind;
    s.n = n;
    s.n_eq = n_eq;
    s.n_in = n_in;
    s.box = box;
  }
  current_ = slots_[found].get();
  slot_ = found;
  current_->qp.resize(n, n_eq, n_in, box);
  return current_->qp;
}

void Hierarchy::call(LevelSolver& solver, const std::string& level, Answer& a) {
  a.solved = true;
  a.success = false;
  a.accepted = false;
  a.has_z = false;
  a.refusal.clear();
  Slot& s = *current_;
  a.qp_x = &s.x;
  a.z = &s.z;
  const auto t0 = std::chrono::steady_clock::now();
  a.success = solver.solve(pool_, s.handle, slot_, reshaped_, level, s.qp, s.x, s.z, a.has_z);
  solver_seconds_ +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void Hierarchy::hold(const Matrix& C, const Vector& lo, const Vector& hi, const Vector* shift) {
  Workspace& ws = *ws_;
  if (ws.n_held == static_cast<int>(ws.held.size())) ws.held.emplace_back();
  Held& h = ws.held[static_cast<size_t>(ws.n_held++)];
  h.C = &C;
  h.lo = lo;
  h.hi = hi;
  if (shift) {
    h.lo += *shift;
    h.hi += *shift;
  }
}

double Hierarchy::held_violation(const HardConstraints& hard, ConstRef x) {
  const Workspace& ws = *ws_;
  double worst = 0.0;
  if (hard.C.rows()) {
    auto c = sized(cx_, hard.C.rows());
    c.noalias() = hard.C * x;
    worst = relative_violation(c, hard.l, hard.u);
  }
  if (hard.has_box()) worst = std::max(worst, relative_violation(x, hard.lb, hard.ub));
  for (int j = 0; j < ws.n_held; ++j) {
    const Held& h = ws.held[static_cast<size_t>(j)];
    auto c = sized(cx_, h.C->rows());
    c.noalias() = *h.C * x;
    worst = std::max(worst, relative_violation(c, h.lo, h.hi));
  }
  return worst;
}

bool Hierarchy::check(const HardConstraints& hard, ConstRef x, double relax, Answer& a) {
  // the largest violation beyond the widening relative to 1 + the problem's scale, as the
  // independent check measures a primal residual (see _held_excess)
  const Workspace& ws = *ws_;
  double worst = 0.0, scale = 0.0;
  auto add = [&](const std::pair<double, double>& part) {
    worst = std::max(worst, part.first);
    scale = std::max(scale, part.second);
  };
  if (hard.A.rows()) {  // the equality rows' scale (the rows themselves are met by construction)
    auto c = sized(cx_, hard.A.rows());
    c.noalias() = hard.A * x;
    scale = std::max(max_abs(c), max_abs(hard.b));
  }
  if (hard.C.rows()) {
    auto c = sized(cx_, hard.C.rows());
    c.noalias() = hard.C * x;
    add(excess_and_scale(c, hard.l, hard.u, relax));
  }
  if (hard.has_box()) add(excess_and_scale(x, hard.lb, hard.ub, relax));
  for (int j = 0; j < ws.n_held; ++j) {
    const Held& h = ws.held[static_cast<size_t>(j)];
    auto c = sized(cx_, h.C->rows());
    c.noalias() = *h.C * x;
    add(excess_and_scale(c, h.lo, h.hi, relax));
  }
  const double excess = worst / (1.0 + scale);
  if (excess <= accept_tol_) return true;
  char text[160];
  std::snprintf(text, sizeof text,
                "reported solved but violates a bound or a held inequality by %.1e > %.0e "
                "(relative to the problem's scale)",
                excess, accept_tol_);
  a.success = false;
  a.refusal = text;
  return false;
}

void Hierarchy::add_result(const PriorityLevel& lv, const Vector& x) {
  Workspace& ws = *ws_;
  if (ws.n_results == static_cast<int>(ws.result.levels.size())) ws.result.levels.emplace_back();
  LevelResult& r = ws.result.levels[static_cast<size_t>(ws.n_results++)];
  r.name = lv.name;
  r.w.resize(lv.A.rows());
  r.w.noalias() = lv.A * x;
  r.w -= lv.b;
  if (lv.C.rows()) {
    auto c = sized(cx_, lv.C.rows());
    c.noalias() = lv.C * x;
    violation(c, lv.l, lv.u, r.v);
  } else {
    r.v.resize(0);
  }
}

void Hierarchy::add_merged(Eigen::Ref<RowMatrix> H, Eigen::Ref<Vector> g, const Merged& merged,
                           const Matrix* Z, const Vector* x_p) {
  for (const PriorityLevel* level : merged) {
    const PriorityLevel& f = *level;
    if (Z == nullptr) {
      H.noalias() += f.weight * (f.A.transpose() * f.A);
      g.noalias() -= f.weight * (f.A.transpose() * f.b);
    } else {
      auto FZ = sized(fz_, f.A.rows(), Z->cols());
      FZ.noalias() = f.A * (*Z);
      H.noalias() += f.weight * (FZ.transpose() * FZ);
      auto r = sized(cx_, f.A.rows());
      r.noalias() = f.A * (*x_p);
      r -= f.b;
      g.noalias() += f.weight * (FZ.transpose() * r);
    }
  }
}

const HierarchyResult& Hierarchy::result() const {
  static const HierarchyResult empty;
  return ws_ == nullptr ? empty : ws_->result;
}

Hierarchy::Workspace& Hierarchy::workspace(const HardConstraints& hard,
                                           const std::vector<PriorityLevel>& soft,
                                           const HierarchyOptions& options) {
  // the shape: the strategy, the hard constraints' and every level's sizes
  const size_t size = 5 + 2 * soft.size();
  auto at = [&](size_t i) -> int {
    switch (i) {
      case 0: return static_cast<int>(options.strategy);
      case 1: return hard.n();
      case 2: return static_cast<int>(hard.A.rows());
      case 3: return static_cast<int>(hard.C.rows());
      case 4: return hard.has_box() ? 1 : 0;
      default: {
        const PriorityLevel& lv = soft[(i - 5) / 2];
        return static_cast<int>((i - 5) % 2 == 0 ? lv.A.rows() : lv.C.rows());
      }
    }
  };
  for (auto& space : spaces_) {
    if (space->shape.size() != size) continue;
    bool same = true;
    for (size_t i = 0; i < size && same; ++i) same = space->shape[i] == at(i);
    if (same) return *space;
  }
  spaces_.push_back(std::make_unique<Workspace>());
  Workspace& ws = *spaces_.back();
  ws.shape.resize(size);
  for (size_t i = 0; i < size; ++i) ws.shape[i] = at(i);
  ws.levels.resize(soft.size());
  return ws;
}

const HierarchyResult& Hierarchy::solve(const HardConstraints& hard,
                                        const std::vector<PriorityLevel>& soft, int n_finals,
                                        const HierarchyOptions& options, LevelSolver& solver) {
  solver_seconds_ = 0.0;
  accept_tol_ = options.accept_tol;
  const int n_soft = static_cast<int>(soft.size());
  if (options.strategy == Strategy::kWeighted) {
    if (options.handles < 1) throw std::invalid_argument("hierarchy: one solver handle needed");
  } else if (options.handles < n_soft) {
    throw std::invalid_argument("hierarchy: one solver handle per level (and per final)");
  }
  ws_ = &workspace(hard, soft, options);
  HierarchyResult& out = ws_->result;
  out.ok = false;
  out.failed_level.clear();
  out.message.clear();
  out.retries = 0;
  ws_->n_results = 0;
  ws_->n_held = 0;
  if (options.strategy == Strategy::kWeighted) {
    solve_weighted(hard, soft, solver);
  } else {
    const bool merge = options.merge_finals && n_soft - n_finals > 0 && n_finals > 0;
    solve_sequential(hard, soft, merge ? n_soft - n_finals : n_soft, options.handles,
                     options.strategy == Strategy::kNullspace, options.prox,
                     options.slack_free_first, solver);
  }
  // (a failed solve has fewer levels: the rest are dropped, their storage with them)
  if (out.levels.size() != static_cast<size_t>(ws_->n_results))
    out.levels.resize(static_cast<size_t>(ws_->n_results));
  return out;
}

void Hierarchy::solve_weighted(const HardConstraints& hard,
                               const std::vector<PriorityLevel>& soft, LevelSolver& solver) {
  const Index n = hard.n();
  Index r_total = 0;
  for (const auto& lv : soft) r_total += lv.C.rows();
  const Index nx = n + r_total;
  const Index n_in = hard.C.rows() + r_total;
  QpBuffers& qp = prepare(0, 0, static_cast<int>(nx), static_cast<int>(hard.A.rows()),
                          static_cast<int>(n_in), hard.has_box());
  Index col = n, row = hard.C.rows();
  for (const auto& lv : soft) {
    qp.H.topLeftCorner(n, n).noalias() += lv.weight * (lv.A.transpose() * lv.A);
    qp.g.head(n).noalias() -= lv.weight * (lv.A.transpose() * lv.b);
    const Index r = lv.C.rows();
    if (r) {
      qp.H.block(col, col, r, r).diagonal().array() += lv.weight;
      qp.C.block(row, 0, r, n) = lv.C;
      qp.C.block(row, col, r, r).diagonal().setConstant(-1.0);
      qp.l.segment(row, r) = lv.l;
      qp.u.segment(row, r) = lv.u;
    }
    col += r;
    row += r;
  }
  qp.A.leftCols(n) = hard.A;
  qp.b = hard.b;
  qp.C.topLeftCorner(hard.C.rows(), n) = hard.C;
  qp.l.head(hard.C.rows()) = hard.l;
  qp.u.head(hard.C.rows()) = hard.u;
  if (hard.has_box()) {
    qp.lb.head(n) = hard.lb;
    qp.ub.head(n) = hard.ub;
  }
  HierarchyResult& out = ws_->result;
  Answer& a = answer_;
  call(solver, kWeighted, a);
  // (only the hard constraints are held)
  if (!a.success || !check(hard, a.qp_x->head(n), 0.0, a)) {
    out.x.setZero(n);
    out.failed_level = kWeighted;
    out.message = a.refusal;
    return;
  }
  out.x = a.qp_x->head(n);
  out.ok = true;
  for (const auto& lv : soft) add_result(lv, out.x);
}

void Hierarchy::cascade_level(const HardConstraints& hard, const PriorityLevel& lv,
                              const Matrix& Et, const Vector& e, LevelWork& w, int handle,
                              double relax, const Vector& center, double prox,
                              const Merged& merged, bool hard_own, LevelSolver& solver,
                              Answer& a) {
  // QP over z = (x, w, v): min ½‖w‖² + ½‖v‖² + ½ prox ‖P (x − center)‖², A x − w = b,
  // l ≤ C x − v ≤ u, E x = e, and the hard constraints (widened by relax)
  a.solved = a.success = a.accepted = false;
  const Workspace& ws = *ws_;
  const Index n = hard.n(), m = lv.A.rows(), r_own = lv.C.rows(), r = hard_own ? 0 : r_own;
  const Index nx = n + m + r, pe = Et.cols();
  const Index ha = hard.A.rows(), hc = hard.C.rows();
  Index n_in = hc + r_own;
  for (int j = 0; j < ws.n_held; ++j) n_in += ws.held[static_cast<size_t>(j)].C->rows();
  QpBuffers& qp = prepare(handle, 0, static_cast<int>(nx), static_cast<int>(ha + pe + m),
                          static_cast<int>(n_in), hard.has_box());
  if (prox) {
    // regularise only the feasible directions (those the held equalities leave free) that
    // the level's objective does not see: P = Z_f (I − R_aᵀ R_a) Z_fᵀ, Z_f a null-space basis
    // of [hard A; E], R_a a row-space basis of A Z_f
    w.stack.resize(ha + pe, n);
    w.stack.topRows(ha) = hard.A;
    w.stack.bottomRows(pe) = Et.transpose();
    w.fbases.factor(w.stack, false, true);
    const Matrix& Zf = w.fbases.Z();
    w.AZf.noalias() = lv.A * Zf;
    w.nbases.factor(w.AZf, true, false);
    const Matrix& Ra = w.nbases.Q1();  // R_aᵀ
    w.N.noalias() = -Ra * Ra.transpose();
    w.N.diagonal().array() += 1.0;
    w.ZN.noalias() = Zf * w.N;
    w.P.noalias() = w.ZN * Zf.transpose();
    qp.H.topLeftCorner(n, n) = prox * w.P;
    qp.g.head(n).noalias() = -prox * (w.P * center);
  }
  qp.H.bottomRightCorner(m + r, m + r).diagonal().setOnes();
  add_merged(qp.H.topLeftCorner(n, n), qp.g.head(n), merged, nullptr, nullptr);
  // equalities: the hard ones, the held ones, the level's
  qp.A.topLeftCorner(ha, n) = hard.A;
  qp.b.head(ha) = hard.b;
  qp.A.block(ha, 0, pe, n) = Et.transpose();
  qp.b.segment(ha, pe) = e;
  qp.A.block(ha + pe, 0, m, n) = lv.A;
  qp.A.block(ha + pe, n, m, m).diagonal().setConstant(-1.0);
  qp.b.tail(m) = lv.b;
  // inequalities: the hard ones and the levels' above (widened), the level's own
  Index row = 0;
  qp.C.topLeftCorner(hc, n) = hard.C;
  widen(hard.l, hard.u, relax, qp.l.segment(0, hc), qp.u.segment(0, hc));
  row += hc;
  for (int j = 0; j < ws.n_held; ++j) {
    const Held& h = ws.held[static_cast<size_t>(j)];
    const Index rj = h.C->rows();
    qp.C.block(row, 0, rj, n) = *h.C;
    widen(h.lo, h.hi, relax, qp.l.segment(row, rj), qp.u.segment(row, rj));
    row += rj;
  }
  if (r_own) {
    qp.C.block(row, 0, r_own, n) = lv.C;
    if (r) qp.C.block(row, n + m, r_own, r).diagonal().setConstant(-1.0);
    qp.l.segment(row, r_own) = lv.l;
    qp.u.segment(row, r_own) = lv.u;
  }
  if (hard.has_box()) widen(hard.lb, hard.ub, relax, qp.lb.head(n), qp.ub.head(n));
  call(solver, lv.name, a);
  if (!a.success || !check(hard, a.qp_x->head(n), relax, a)) return;
  if (hard_own && !own_multipliers_vanish(*a.qp_x, *a.z, a.has_z, r_own)) return;
  a.accepted = true;
  ws_->a_x = a.qp_x->head(n);
}

void Hierarchy::nullspace_level(const HardConstraints& hard, const PriorityLevel& lv,
                                const Vector& x_p, const Matrix& Z, LevelWork& w, int handle,
                                int kind, double relax, double prox, const Merged& merged,
                                bool hard_own, LevelSolver& solver, Answer& a) {
  // QP over (y, v), x = x_p + Z y: min ½‖A Z y − (b − A x_p)‖² + ½‖v‖²
  a.solved = a.success = a.accepted = false;
  Workspace& ws = *ws_;
  const Index n = hard.n(), d = Z.cols(), m = lv.A.rows(), r_own = lv.C.rows();
  const Index r = hard_own ? 0 : r_own;
  if (d == 0) {  // nothing left free: x_p is the level's optimum
    a.accepted = true;
    ws.a_x = x_p;
    return;
  }
  const Index nx = d + r;
  // the hard box as rows: those with a finite bound
  box_rows_.clear();
  if (hard.has_box())
    for (Index j = 0; j < n; ++j)
      if (std::isfinite(hard.lb(j)) || std::isfinite(hard.ub(j))) box_rows_.push_back(j);
  const Index nb = static_cast<Index>(box_rows_.size());
  Index n_in = hard.C.rows() + nb + r_own;
  for (int j = 0; j < ws.n_held; ++j) n_in += ws.held[static_cast<size_t>(j)].C->rows();
  QpBuffers& qp = prepare(handle, kind, static_cast<int>(nx), 0, static_cast<int>(n_in), false);
  Matrix& AZ = kind == 0 ? w.AZ : w.pAZ;
  AZ.noalias() = lv.A * Z;
  auto H = qp.H.topLeftCorner(d, d);
  H.noalias() = AZ.transpose() * AZ;
  // the proximal term centred on x_p: ‖Z y‖² = ‖y‖² (Z orthonormal), only in the directions
  // the level's objective does not see: prox (I − Rᵀ R), R a row-space basis of A Z
  if (prox) {
    w.nbases.factor(AZ, true, false);
    const Matrix& Ra = w.nbases.Q1();
    H.noalias() -= prox * (Ra * Ra.transpose());
    H.diagonal().array() += prox;
  }
  qp.H.bottomRightCorner(r, r).diagonal().setOnes();
  {
    auto residual = sized(cx_, m);  // A x_p − b
    residual.noalias() = lv.A * x_p;
    residual -= lv.b;
    qp.g.head(d).noalias() = AZ.transpose() * residual;
  }
  add_merged(H, qp.g.head(d), merged, &Z, &x_p);
  Index row = 0;
  auto add = [&](const Matrix& C, const Vector& lower, const Vector& upper, bool slack) {
    const Index rc = C.rows();
    if (!rc) return;
    qp.C.block(row, 0, rc, d).noalias() = C * Z;
    if (slack && r) qp.C.block(row, d, rc, r).diagonal().setConstant(-1.0);
    auto lo = qp.l.segment(row, rc);
    auto hi = qp.u.segment(row, rc);
    if (slack) {
      lo = lower;
      hi = upper;
    } else {
      widen(lower, upper, relax, lo, hi);
    }
    auto shift = sized(cx_, rc);
    shift.noalias() = C * x_p;
    lo -= shift;
    hi -= shift;
    row += rc;
  };
  add(hard.C, hard.l, hard.u, false);
  for (Index j = 0; j < nb; ++j) {
    const Index c = box_rows_[static_cast<size_t>(j)];
    qp.C.row(row + j).head(d) = Z.row(c);
    const double lo = hard.lb(c), hi = hard.ub(c);
    qp.l(row + j) = (relax == 0.0 ? lo : lo - relax * (1.0 + std::abs(lo))) - x_p(c);
    qp.u(row + j) = (relax == 0.0 ? hi : hi + relax * (1.0 + std::abs(hi))) - x_p(c);
  }
  row += nb;
  for (int j = 0; j < ws.n_held; ++j) {
    const Held& h = ws.held[static_cast<size_t>(j)];
    add(*h.C, h.lo, h.hi, false);
  }
  add(lv.C, lv.l, lv.u, true);
  call(solver, lv.name, a);
  if (!a.success) return;
  ws.a_x = x_p;
  ws.a_x.noalias() += Z * a.qp_x->head(d);
  if (!check(hard, ws.a_x, relax, a)) return;
  if (hard_own && !own_multipliers_vanish(*a.qp_x, *a.z, a.has_z, r_own)) return;
  a.accepted = true;
}

void Hierarchy::solve_sequential(const HardConstraints& hard,
                                 const std::vector<PriorityLevel>& soft, int n_levels,
                                 int n_handles, bool nullspace, double prox,
                                 bool slack_free_first, LevelSolver& solver) {
  Workspace& ws = *ws_;
  const Index n = hard.n();
  const int n_soft = static_cast<int>(soft.size());
  merged_.clear();
  for (int j = n_levels; j < n_soft; ++j) merged_.push_back(&soft[j]);
  // handles of the slack QPs: a second set when the caller holds one
  const int second = n_handles >= 2 * n_soft ? n_soft : 0;
  held_rows_.clear();
  HierarchyResult& out = ws.result;
  Answer& a = answer_;
  Vector& x = ws.x;
  Vector& x_p = ws.x_p;
  bool has_x = false;
  // one factorisation of the hard equalities: bases and the minimum-norm solution x_p
  // (the cascade projects the held rows with R, the null-space strategy works in Z)
  ws.hard.factor(hard.A, !nullspace, nullspace);
  ws.hard.min_norm(hard.A, hard.b, x_p);
  const Matrix* Z = nullspace ? &ws.hard.Z() : nullptr;
  const Matrix* Et = nullptr;  // the held equalities' rows not fixed by the hard ones, as Eᵀ
  const Vector* e = nullptr;
  const int last = n_levels - 1;
  bool skip = false;
  double carried = 0.0;  // relative violation the levels solved so far left (see kFeasTol)

  // Z ← Z Z_l, Z_l a null-space basis of A Z (into level i's workspace)
  auto eliminate = [&](const Matrix& A, int i) {
    LevelWork& w = ws.levels[static_cast<size_t>(i)];
    w.AZ.noalias() = A * (*Z);
    w.bases.factor(w.AZ, false, true);
    w.Z.noalias() = (*Z) * w.bases.Z();
    Z = &w.Z;
  };
  // the level's inequalities held with its optimal slacks (its result's entry k)
  auto hold_inequalities = [&](const PriorityLevel& lv, int k) {
    if (lv.C.rows()) hold(lv.C, lv.l, lv.u, &out.levels[static_cast<size_t>(k)].v);
  };

  for (int i = 0; i <= last; ++i) {
    if (skip) {  // solved together with the level above
      skip = false;
      continue;
    }
    const PriorityLevel& lv = soft[i];
    LevelWork& w = ws.levels[static_cast<size_t>(i)];
    const Merged& extra = i == last ? merged_ : none_;
    // growing with the level, so the previous optimum is strictly inside the widened set
    const double relax = kFeasTol * i + carried;
    if (nullspace && lv.hard_if_feasible && i < last && soft[i + 1].C.rows() == 0) {
      // level lv held hard inside the next level's QP (see _feasible_pair)
      const PriorityLevel& nxt = soft[i + 1];
      bool met = true;
      const Vector* x_l = &x_p;
      const Matrix* Z_l = Z;
      if (lv.A.rows()) {
        // (A Z as the level alone has it: its own QP and its elimination take the same)
        w.AZ.noalias() = lv.A * (*Z);
        w.rhs = lv.b;
        w.rhs.noalias() -= lv.A * x_p;
        w.pbases.factor(w.AZ, false, true);
        w.pbases.min_norm(w.AZ, w.rhs, w.y);
        w.x_l = x_p;
        w.x_l.noalias() += (*Z) * w.y;
        x_l = &w.x_l;
        const double scale = 1.0 + max_abs(lv.b);
        auto residual = sized(cx_, lv.A.rows());
        residual.noalias() = lv.A * w.x_l;
        residual -= lv.b;
        // the equalities cannot be met together with the levels above
        met = max_abs(residual) <= 1e3 * kRankTol * scale;
        w.pZ.noalias() = (*Z) * w.pbases.Z();
        Z_l = &w.pZ;
      }
      if (met) {
        hold(lv.C, lv.l, lv.u, nullptr);
        nullspace_level(hard, nxt, *x_l, *Z_l, w, i, 1, relax + kFeasTol, 0.0,
                        i + 1 == last ? merged_ : none_, false, solver, a);
        --ws.n_held;
        if (a.accepted) {
          x = ws.a_x;
          has_x = true;
          const int k = ws.n_results;
          add_result(lv, x);
          add_result(nxt, x);
          if (i + 1 == last) break;
          held_rows_.push_back(&lv.A);
          held_rows_.push_back(&nxt.A);
          // (the held level's own rows, shifted by its slacks, hold at x by construction)
          carried = std::max(carried, held_violation(hard, x));
          hold_inequalities(lv, k);
          Z = Z_l;
          if (nxt.A.rows()) eliminate(nxt.A, i + 1);
          x_p = x;
          skip = true;
          continue;
        }
      }
    }
    if (!nullspace) {
      // the held rows E, then only their part not already fixed by the hard equalities
      // (E − E Rᵀ R, R their row-space basis), so that [hard A; E] keeps full row rank
      Index p = 0;
      for (const Matrix* rows : held_rows_) p += rows->rows();
      w.E.resize(p, n);
      p = 0;
      for (const Matrix* rows : held_rows_) {
        w.E.middleRows(p, rows->rows()) = *rows;
        p += rows->rows();
      }
      const Matrix& Q1 = ws.hard.Q1();  // Rᵀ
      w.EQ.noalias() = w.E * Q1;
      w.Ep = w.E;
      w.Ep.noalias() -= w.EQ * Q1.transpose();
      w.bases.factor(w.Ep, true, false);
      Et = &w.bases.Q1();
      if (has_x)
        w.e.noalias() = Et->transpose() * x;
      else
        w.e.resize(0);
      e = &w.e;
    }
    const Vector& center = has_x ? x : x_p;
    // the bare level first; the proximal term only when the backend fails on it
    a.solved = a.success = a.accepted = false;
    const bool own = lv.C.rows() > 0;
    if (slack_free_first && own) {
      // the level's inequalities hard: its optimum when their multipliers vanish
      if (nullspace)
        nullspace_level(hard, lv, x_p, *Z, w, i, 0, relax, 0.0, extra, true, solver, a);
      else
        cascade_level(hard, lv, *Et, *e, w, i, relax, center, 0.0, extra, true, solver, a);
    }
    if (!a.accepted) {
      const int handle = slack_free_first && own ? second + i : i;
      const int tries = prox > 0.0 ? 2 : 1;
      for (int t = 0; t < tries; ++t) {
        const double eps = t == 0 ? 0.0 : prox;
        if (nullspace)
          nullspace_level(hard, lv, x_p, *Z, w, handle, 0, relax, eps, extra, false, solver, a);
        else
          cascade_level(hard, lv, *Et, *e, w, handle, relax, center, eps, extra, false, solver,
                        a);
        if (!a.solved || (a.success && a.accepted)) break;
        if (t == 0 && prox > 0.0) ++out.retries;
      }
    }
    if (a.solved && (!a.success || !a.accepted)) {
      if (has_x)
        out.x = x;
      else
        out.x.setZero(n);
      out.failed_level = lv.name;
      out.message = a.refusal;
      return;
    }
    x = ws.a_x;
    has_x = true;
    const int k = ws.n_results;
    add_result(lv, x);
    // hold this level's optimum for the levels below (nothing to hold after the last)
    if (i == last) break;
    if (lv.A.rows()) {
      held_rows_.push_back(&lv.A);
      if (nullspace) eliminate(lv.A, i);
    }
    carried = std::max(carried, held_violation(hard, x));
    hold_inequalities(lv, k);
    if (nullspace) x_p = x;
  }
  for (const PriorityLevel* f : merged_) add_result(*f, x);
  out.x = x;
  out.ok = true;
}

}  // namespace wbcbench
