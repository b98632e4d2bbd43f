#include "qp/hierarchy.hpp"

#include <Eigen/QR>
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
constexpr double kInf = std::numeric_limits<double>::infinity();

using Index = Eigen::Index;

// Ranks count |R_ii| > tol · max(1, |R_00|), as the reference does.
int qr_rank(const Eigen::ColPivHouseholderQR<Matrix>& qr, double tol) {
  const Index k = std::min(qr.rows(), qr.cols());
  if (k == 0) return 0;
  const auto d = qr.matrixQR().diagonal().cwiseAbs();
  const double threshold = tol * std::max(1.0, d(0));
  return static_cast<int>((d.array() > threshold).count());
}

// Null-space projector I − Rᵀ R of A (n, n).
Matrix null_projector(const Matrix& A) {
  Matrix R;
  row_space_and_null_space(A, &R, nullptr);
  Matrix P = -R.transpose() * R;
  P.diagonal().array() += 1.0;
  return P;
}

// From Eᵀ P = Q R of rank r: the row-space basis R = Q₁ᵀ (r, n) and the null-space basis
// Z = Q₂ (n, n − r) of E, where asked for (non-null); only those columns of Q are formed, the
// reflectors applied to the identity's columns.
void bases(const Eigen::ColPivHouseholderQR<Matrix>& qr, int rank, Matrix* R, Matrix* Z) {
  const Index n = qr.rows();
  if (R) {
    Matrix Q1 = Matrix::Identity(n, rank);
    Q1.applyOnTheLeft(qr.householderQ());
    *R = Q1.transpose();
  }
  if (Z) {
    Matrix Q2 = Matrix::Zero(n, n - rank);
    Q2.bottomRows(n - rank).setIdentity();
    Q2.applyOnTheLeft(qr.householderQ());
    *Z = std::move(Q2);
  }
}

// Row-space basis R, null-space basis Z and minimum-norm solution x_p of A x = b, one QR.
// R or Z may be null: only the columns of Q asked for are formed (the reflectors applied to the
// identity's columns), which is most of the cost on a wide A.
void hard_factor(const Matrix& A, const Vector& b, Matrix* R, Matrix* Z, Vector& x_p) {
  const Index n = A.cols();
  if (A.rows() == 0) {
    if (R) R->setZero(0, n);
    if (Z) Z->setIdentity(n, n);
    x_p.setZero(n);
    return;
  }
  Eigen::ColPivHouseholderQR<Matrix> qr(A.transpose());  // Aᵀ P = Q R
  const int rank = qr_rank(qr, kRankTol);
  bases(qr, rank, R, Z);
  if (rank == A.rows()) {
    // Pᵀ A = Rᵀ Qᵀ: x = Q₁ y with R₁ᵀ y = Pᵀ b is the minimum-norm solution
    const Vector pb = qr.colsPermutation().transpose() * b;
    x_p.setZero(n);
    x_p.head(rank) = qr.matrixQR()
                         .topLeftCorner(rank, rank)
                         .triangularView<Eigen::Upper>()
                         .transpose()
                         .solve(pb);
    x_p.applyOnTheLeft(qr.householderQ());
  } else {
    x_p = A.completeOrthogonalDecomposition().solve(b);
  }
}

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
double relative_violation(const Vector& Cx, const Vector& lower, const Vector& upper) {
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
std::pair<double, double> excess_and_scale(const Vector& Cx, const Vector& lower,
                                           const Vector& upper, double relax) {
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

// signed slack v that puts C x − v inside [l, u] with the smallest |v|
Vector violation(const Vector& Cx, const Vector& lower, const Vector& upper) {
  Vector v(Cx.size());
  for (Index i = 0; i < Cx.size(); ++i)
    v(i) = Cx(i) > upper(i) ? Cx(i) - upper(i) : (Cx(i) < lower(i) ? Cx(i) - lower(i) : 0.0);
  return v;
}

LevelResult level_result(const PriorityLevel& lv, const Vector& x) {
  LevelResult r;
  r.name = lv.name;
  r.w = lv.A * x - lv.b;
  r.v = lv.C.rows() ? violation(lv.C * x, lv.l, lv.u) : Vector(0);
  return r;
}

// the finals merged into a level's cost: H += w FᵀF, g −= w Fᵀ f over x (Z empty), or over y
// with x = x_p + Z y
void add_merged(Eigen::Ref<RowMatrix> H, Eigen::Ref<Vector> g, const Hierarchy::Merged& merged,
                const Matrix* Z, const Vector* x_p) {
  for (const PriorityLevel* level : merged) {
    const PriorityLevel& f = *level;
    if (Z == nullptr) {
      H.noalias() += f.weight * (f.A.transpose() * f.A);
      g.noalias() -= f.weight * (f.A.transpose() * f.b);
    } else {
      const Matrix FZ = f.A * (*Z);
      H.noalias() += f.weight * (FZ.transpose() * FZ);
      g.noalias() += f.weight * (FZ.transpose() * (f.A * (*x_p) - f.b));
    }
  }
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

Matrix vstack(const std::vector<const Matrix*>& blocks, Index n) {
  Index rows = 0;
  for (const Matrix* b : blocks) rows += b->rows();
  Matrix out(rows, n);
  Index r = 0;
  for (const Matrix* b : blocks) {
    out.middleRows(r, b->rows()) = *b;
    r += b->rows();
  }
  return out;
}

}  // namespace

void row_space_and_null_space(const Matrix& E, Matrix* R, Matrix* Z, double tol) {
  const Index n = E.cols();
  if (E.rows() == 0 || n == 0) {  // (an empty factorisation)
    if (R) R->setZero(0, n);
    if (Z) Z->setIdentity(n, n);
    return;
  }
  Eigen::ColPivHouseholderQR<Matrix> qr(E.transpose());
  const int rank = qr_rank(qr, tol);
  bases(qr, rank, R, Z);
}

void row_space_and_null_space(const Matrix& E, Matrix& R, Matrix& Z, double tol) {
  row_space_and_null_space(E, &R, &Z, tol);
}

QpBuffers& Hierarchy::prepare(int handle, int kind, int n, int n_eq, int n_in, bool box) {
  const int slot = 2 * handle + kind;
  while (static_cast<int>(slots_.size()) <= slot) slots_.push_back(std::make_unique<QpBuffers>());
  QpBuffers& qp = *slots_[slot];
  reshaped_ = qp.reshapes(n, n_eq, n_in, box) || qp.H.size() == 0;
  qp.resize(n, n_eq, n_in, box);
  handle_ = handle;
  slot_ = slot;
  return qp;
}

Hierarchy::Answer Hierarchy::call(LevelSolver& solver, const std::string& level) {
  Answer a;
  a.solved = true;
  const auto t0 = std::chrono::steady_clock::now();
  a.success = solver.solve(pool_, handle_, slot_, reshaped_, level, *slots_[slot_], a.qp_x, a.z,
                           a.has_z);
  solver_seconds_ +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return a;
}

double Hierarchy::held_violation(const HardConstraints& hard, const Vector& x) const {
  double worst = 0.0;
  if (hard.C.rows()) worst = relative_violation(hard.C * x, hard.l, hard.u);
  if (hard.has_box()) worst = std::max(worst, relative_violation(x, hard.lb, hard.ub));
  for (size_t j = 0; j < prev_C_.size(); ++j)
    worst = std::max(worst, relative_violation(prev_C_[j] * x, prev_lo_[j], prev_hi_[j]));
  return worst;
}

bool Hierarchy::check(const HardConstraints& hard, const Vector& x, double relax,
                      Answer& a) const {
  // the largest violation beyond the widening relative to 1 + the problem's scale, as the
  // independent check measures a primal residual (see _held_excess)
  double worst = 0.0, scale = 0.0;
  auto add = [&](const std::pair<double, double>& part) {
    worst = std::max(worst, part.first);
    scale = std::max(scale, part.second);
  };
  if (hard.A.rows())  // the equality rows' scale (the rows themselves are met by construction)
    scale = std::max((hard.A * x).cwiseAbs().maxCoeff(), hard.b.cwiseAbs().maxCoeff());
  if (hard.C.rows()) add(excess_and_scale(hard.C * x, hard.l, hard.u, relax));
  if (hard.has_box()) add(excess_and_scale(x, hard.lb, hard.ub, relax));
  for (size_t j = 0; j < prev_C_.size(); ++j)
    add(excess_and_scale(prev_C_[j] * x, prev_lo_[j], prev_hi_[j], relax));
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

HierarchyResult Hierarchy::solve(const HardConstraints& hard,
                                 const std::vector<PriorityLevel>& soft, int n_finals,
                                 const HierarchyOptions& options, LevelSolver& solver) {
  solver_seconds_ = 0.0;
  accept_tol_ = options.accept_tol;
  const int n_soft = static_cast<int>(soft.size());
  if (options.strategy == Strategy::kWeighted) {
    if (options.handles < 1) throw std::invalid_argument("hierarchy: one solver handle needed");
    return solve_weighted(hard, soft, solver);
  }
  if (options.handles < n_soft)
    throw std::invalid_argument("hierarchy: one solver handle per level (and per final)");
  const bool merge = options.merge_finals && n_soft - n_finals > 0 && n_finals > 0;
  return solve_sequential(hard, soft, merge ? n_soft - n_finals : n_soft, options.handles,
                          options.strategy == Strategy::kNullspace, options.prox,
                          options.slack_free_first, solver);
}

HierarchyResult Hierarchy::solve_weighted(const HardConstraints& hard,
                                          const std::vector<PriorityLevel>& soft,
                                          LevelSolver& solver) {
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
  HierarchyResult out;
  Answer a = call(solver, "weighted");
  prev_C_.clear();  // (only the hard constraints are held)
  prev_lo_.clear();
  prev_hi_.clear();
  if (!a.success || !check(hard, a.qp_x.head(n), 0.0, a)) {
    out.x.setZero(n);
    out.failed_level = "weighted";
    out.message = a.refusal;
    return out;
  }
  out.x = a.qp_x.head(n);
  out.ok = true;
  for (const auto& lv : soft) out.levels.push_back(level_result(lv, out.x));
  return out;
}

Hierarchy::Answer Hierarchy::cascade_level(const HardConstraints& hard, const PriorityLevel& lv,
                                           const Matrix& E, const Vector& e, int handle,
                                           double relax, const Vector& center, double prox,
                                           const Merged& merged,
                                           bool hard_own, LevelSolver& solver) {
  // QP over z = (x, w, v): min ½‖w‖² + ½‖v‖² + ½ prox ‖P (x − center)‖², A x − w = b,
  // l ≤ C x − v ≤ u, E x = e, and the hard constraints (widened by relax)
  const Index n = hard.n(), m = lv.A.rows(), r_own = lv.C.rows(), r = hard_own ? 0 : r_own;
  const Index nx = n + m + r;
  const Index ha = hard.A.rows(), hc = hard.C.rows();
  Index n_in = hc + r_own;
  for (const auto& C : prev_C_) n_in += C.rows();
  QpBuffers& qp = prepare(handle, 0, static_cast<int>(nx), static_cast<int>(ha + E.rows() + m),
                          static_cast<int>(n_in), hard.has_box());
  if (prox) {
    // regularise only the feasible directions (those the held equalities leave free) that
    // the level's objective does not see
    Matrix Zf;
    row_space_and_null_space(vstack({&hard.A, &E}, n), nullptr, &Zf);
    const Matrix P = Zf * null_projector(lv.A * Zf) * Zf.transpose();
    qp.H.topLeftCorner(n, n) = prox * P;
    qp.g.head(n).noalias() = -prox * (P * center);
  }
  qp.H.bottomRightCorner(m + r, m + r).diagonal().setOnes();
  add_merged(qp.H.topLeftCorner(n, n), qp.g.head(n), merged, nullptr, nullptr);
  // equalities: the hard ones, the held ones, the level's
  qp.A.topLeftCorner(ha, n) = hard.A;
  qp.b.head(ha) = hard.b;
  qp.A.block(ha, 0, E.rows(), n) = E;
  qp.b.segment(ha, E.rows()) = e;
  qp.A.block(ha + E.rows(), 0, m, n) = lv.A;
  qp.A.block(ha + E.rows(), n, m, m).diagonal().setConstant(-1.0);
  qp.b.tail(m) = lv.b;
  // inequalities: the hard ones and the levels' above (widened), the level's own
  Index row = 0;
  qp.C.topLeftCorner(hc, n) = hard.C;
  widen(hard.l, hard.u, relax, qp.l.segment(0, hc), qp.u.segment(0, hc));
  row += hc;
  for (size_t j = 0; j < prev_C_.size(); ++j) {
    const Index rj = prev_C_[j].rows();
    qp.C.block(row, 0, rj, n) = prev_C_[j];
    widen(prev_lo_[j], prev_hi_[j], relax, qp.l.segment(row, rj), qp.u.segment(row, rj));
    row += rj;
  }
  if (r_own) {
    qp.C.block(row, 0, r_own, n) = lv.C;
    if (r) qp.C.block(row, n + m, r_own, r).diagonal().setConstant(-1.0);
    qp.l.segment(row, r_own) = lv.l;
    qp.u.segment(row, r_own) = lv.u;
  }
  if (hard.has_box()) widen(hard.lb, hard.ub, relax, qp.lb.head(n), qp.ub.head(n));
  Answer a = call(solver, lv.name);
  if (!a.success || !check(hard, a.qp_x.head(n), relax, a)) return a;
  if (hard_own && !own_multipliers_vanish(a.qp_x, a.z, a.has_z, r_own)) return a;
  a.accepted = true;
  a.x = a.qp_x.head(n);
  return a;
}

Hierarchy::Answer Hierarchy::nullspace_level(const HardConstraints& hard,
                                             const PriorityLevel& lv, const Vector& x_p,
                                             const Matrix& Z, int handle, int kind,
                                             double relax, double prox,
                                             const Merged& merged,
                                             bool hard_own, LevelSolver& solver) {
  // QP over (y, v), x = x_p + Z y: min ½‖A Z y − (b − A x_p)‖² + ½‖v‖²
  const Index n = hard.n(), d = Z.cols(), r_own = lv.C.rows(), r = hard_own ? 0 : r_own;
  if (d == 0) {  // nothing left free: x_p is the level's optimum
    Answer a;
    a.accepted = true;
    a.x = x_p;
    return a;
  }
  const Index nx = d + r;
  // the hard box as rows: those with a finite bound
  std::vector<Index> box_rows;
  if (hard.has_box())
    for (Index j = 0; j < n; ++j)
      if (std::isfinite(hard.lb(j)) || std::isfinite(hard.ub(j))) box_rows.push_back(j);
  Index n_in = hard.C.rows() + static_cast<Index>(box_rows.size()) + r_own;
  for (const auto& C : prev_C_) n_in += C.rows();
  QpBuffers& qp = prepare(handle, kind, static_cast<int>(nx), 0, static_cast<int>(n_in), false);
  const Matrix AZ = lv.A * Z;
  auto H = qp.H.topLeftCorner(d, d);
  H.noalias() = AZ.transpose() * AZ;
  // the proximal term centred on x_p: ‖Z y‖² = ‖y‖² (Z orthonormal), only in the directions
  // the level's objective does not see
  if (prox) H += prox * null_projector(AZ);
  qp.H.bottomRightCorner(r, r).diagonal().setOnes();
  qp.g.head(d).noalias() = -AZ.transpose() * (lv.b - lv.A * x_p);
  add_merged(H, qp.g.head(d), merged, &Z, &x_p);
  Index row = 0;
  auto add = [&](const Matrix& C, const Vector& lower, const Vector& upper, bool slack) {
    const Index rc = C.rows();
    if (!rc) return;
    qp.C.block(row, 0, rc, d).noalias() = C * Z;
    if (slack && r) qp.C.block(row, d, rc, r).diagonal().setConstant(-1.0);
    const Vector shift = C * x_p;
    auto lo = qp.l.segment(row, rc);
    auto hi = qp.u.segment(row, rc);
    if (slack) {
      lo = lower;
      hi = upper;
    } else {
      widen(lower, upper, relax, lo, hi);
    }
    lo -= shift;
    hi -= shift;
    row += rc;
  };
  add(hard.C, hard.l, hard.u, false);
  if (!box_rows.empty()) {
    const Index nb = static_cast<Index>(box_rows.size());
    for (Index j = 0; j < nb; ++j) {
      const Index c = box_rows[j];
      qp.C.row(row + j).head(d) = Z.row(c);
      const double lo = hard.lb(c), hi = hard.ub(c);
      qp.l(row + j) = (relax == 0.0 ? lo : lo - relax * (1.0 + std::abs(lo))) - x_p(c);
      qp.u(row + j) = (relax == 0.0 ? hi : hi + relax * (1.0 + std::abs(hi))) - x_p(c);
    }
    row += nb;
  }
  for (size_t j = 0; j < prev_C_.size(); ++j) add(prev_C_[j], prev_lo_[j], prev_hi_[j], false);
  add(lv.C, lv.l, lv.u, true);
  Answer a = call(solver, lv.name);
  if (!a.success) return a;
  Vector x = x_p;
  x.noalias() += Z * a.qp_x.head(d);
  if (!check(hard, x, relax, a)) return a;
  if (hard_own && !own_multipliers_vanish(a.qp_x, a.z, a.has_z, r_own)) return a;
  a.accepted = true;
  a.x = std::move(x);
  return a;
}

HierarchyResult Hierarchy::solve_sequential(const HardConstraints& hard,
                                            const std::vector<PriorityLevel>& soft,
                                            int n_levels, int n_handles, bool nullspace,
                                            double prox, bool slack_free_first,
                                            LevelSolver& solver) {
  const Index n = hard.n();
  const int n_soft = static_cast<int>(soft.size());
  Merged merged;
  for (int j = n_levels; j < n_soft; ++j) merged.push_back(&soft[j]);
  // handles of the slack QPs: a second set when the caller holds one
  const int second = n_handles >= 2 * n_soft ? n_soft : 0;
  std::vector<const Matrix*> held_rows;  // equalities held so far, the hard ones excluded
  prev_C_.clear();
  prev_lo_.clear();
  prev_hi_.clear();
  HierarchyResult out;
  Vector x;
  bool has_x = false;
  Matrix Eb(0, n);
  Vector e(0);
  // one factorisation of the hard equalities: bases and the minimum-norm solution x_p
  // (the cascade projects the held rows with R, the null-space strategy works in Z)
  Matrix R_hard, Z;
  Vector x_p;
  hard_factor(hard.A, hard.b, nullspace ? nullptr : &R_hard, nullspace ? &Z : nullptr, x_p);
  const Merged none;
  const int last = n_levels - 1;
  bool skip = false;
  double carried = 0.0;  // relative violation the levels solved so far left (see kFeasTol)

  // the largest relative violation xs leaves on the inequalities the next levels inherit
  auto carried_violation = [&](const Vector& xs) { return held_violation(hard, xs); };
  auto hold_inequalities = [&](const PriorityLevel& lv, const LevelResult& res) {
    if (!lv.C.rows()) return;
    prev_C_.push_back(lv.C);
    prev_lo_.push_back(lv.l + res.v);
    prev_hi_.push_back(lv.u + res.v);
  };
  auto eliminate = [&](const Matrix& A) {  // Z ← Z Z_l, Z_l a null-space basis of A Z
    Matrix Zl;
    row_space_and_null_space(A * Z, nullptr, &Zl);
    Z = Z * Zl;
  };

  for (int i = 0; i <= last; ++i) {
    if (skip) {  // solved together with the level above
      skip = false;
      continue;
    }
    const PriorityLevel& lv = soft[i];
    const Merged& extra = i == last ? merged : none;
    // growing with the level, so the previous optimum is strictly inside the widened set
    const double relax = kFeasTol * i + carried;
    if (nullspace && lv.hard_if_feasible && i < last && soft[i + 1].C.rows() == 0) {
      // level lv held hard inside the next level's QP (see _feasible_pair)
      const PriorityLevel& nxt = soft[i + 1];
      bool met = true;
      Vector x_l = x_p;
      Matrix Z_l = Z;
      if (lv.A.rows()) {
        Matrix Zl;
        Vector y0;
        hard_factor(lv.A * Z, lv.b - lv.A * x_p, nullptr, &Zl, y0);
        x_l.noalias() += Z * y0;
        const double scale = 1.0 + (lv.b.size() ? lv.b.cwiseAbs().maxCoeff() : 0.0);
        // the equalities cannot be met together with the levels above
        met = (lv.A * x_l - lv.b).cwiseAbs().maxCoeff() <= 1e3 * kRankTol * scale;
        Z_l = Z * Zl;
      }
      if (met) {
        prev_C_.push_back(lv.C);
        prev_lo_.push_back(lv.l);
        prev_hi_.push_back(lv.u);
        const Answer a = nullspace_level(hard, nxt, x_l, Z_l, i, 1, relax + kFeasTol, 0.0,
                                         i + 1 == last ? merged : none, false, solver);
        prev_C_.pop_back();
        prev_lo_.pop_back();
        prev_hi_.pop_back();
        if (a.accepted) {
          x = a.x;
          has_x = true;
          const LevelResult res = level_result(lv, x);
          out.levels.push_back(res);
          out.levels.push_back(level_result(nxt, x));
          if (i + 1 == last) break;
          held_rows.push_back(&lv.A);
          held_rows.push_back(&nxt.A);
          // (the held level's own rows, shifted by its slacks, hold at x by construction)
          carried = std::max(carried, carried_violation(x));
          hold_inequalities(lv, res);
          Z = Z_l;
          if (nxt.A.rows()) eliminate(nxt.A);
          x_p = x;
          skip = true;
          continue;
        }
      }
    }
    if (!nullspace) {
      const Matrix E = vstack(held_rows, n);
      // only the part of the held rows not already fixed by the hard equalities, so that
      // [hard A; E] keeps full row rank
      row_space_and_null_space(E - (E * R_hard.transpose()) * R_hard, &Eb, nullptr);
      e = has_x ? Vector(Eb * x) : Vector(0);
    }
    const Vector center = has_x ? x : x_p;
    // the bare level first; the proximal term only when the backend fails on it
    Answer a;
    const bool own = lv.C.rows() > 0;
    if (slack_free_first && own) {
      // the level's inequalities hard: its optimum when their multipliers vanish
      a = nullspace ? nullspace_level(hard, lv, x_p, Z, i, 0, relax, 0.0, extra, true, solver)
                    : cascade_level(hard, lv, Eb, e, i, relax, center, 0.0, extra, true, solver);
    }
    if (!a.accepted) {
      const int handle = slack_free_first && own ? second + i : i;
      const int tries = prox > 0.0 ? 2 : 1;
      for (int t = 0; t < tries; ++t) {
        const double eps = t == 0 ? 0.0 : prox;
        a = nullspace
                ? nullspace_level(hard, lv, x_p, Z, handle, 0, relax, eps, extra, false, solver)
                : cascade_level(hard, lv, Eb, e, handle, relax, center, eps, extra, false,
                                solver);
        if (!a.solved || (a.success && a.accepted)) break;
        if (t == 0 && prox > 0.0) ++out.retries;
      }
    }
    if (a.solved && (!a.success || !a.accepted)) {
      out.x = has_x ? x : Vector(Vector::Zero(n));
      out.failed_level = lv.name;
      out.message = a.refusal;
      return out;
    }
    x = a.x;
    has_x = true;
    const LevelResult res = level_result(lv, x);
    out.levels.push_back(res);
    // hold this level's optimum for the levels below (nothing to hold after the last)
    if (i == last) break;
    if (lv.A.rows()) {
      held_rows.push_back(&lv.A);
      if (nullspace) eliminate(lv.A);
    }
    carried = std::max(carried, carried_violation(x));
    hold_inequalities(lv, res);
    if (nullspace) x_p = x;
  }
  for (const PriorityLevel* f : merged) out.levels.push_back(level_result(*f, x));
  out.x = x;
  out.ok = true;
  return out;
}

}  // namespace wbcbench
