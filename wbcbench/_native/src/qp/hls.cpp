#include "qp/hls.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace wbcbench {

namespace {

using Index = Eigen::Index;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// "singular triangular factor" with LAPACK trtrs' info (1-based index of the zero on the
// diagonal), or 0 when the (size, size) upper triangle is invertible
template <typename D>
Index zero_on_diagonal(const Eigen::MatrixBase<D>& R, Index size) {
  for (Index i = 0; i < size; ++i)
    if (R(i, i) == 0.0) return i + 1;
  return 0;
}

std::string singular(Index info) {
  return "singular triangular factor (LAPACK dtrtrs info=" + std::to_string(info) + ")";
}

}  // namespace

Eigen::Block<Matrix> HlsBuffer::view(Index rows, Index cols) {
  if (m_.rows() < rows || m_.cols() < cols)
    m_.conservativeResize(std::max(rows, m_.rows()), std::max(cols, m_.cols()));
  return m_.topLeftCorner(rows, cols);
}

Eigen::VectorBlock<Vector> head_of(Vector& v, Index n) {
  if (v.size() < n) v.conservativeResize(n);
  return v.head(n);
}

// -- Column-pivoted Householder QR (mirror of pivoted_qr)

Eigen::Block<Matrix> PivotedQr::load(Index q, Index m) {
  q_ = q;
  m_ = m;
  if (h_.rows() < q || h_.cols() < m)
    h_.resize(std::max(q, h_.rows()), std::max(m, h_.cols()));
  return h_.topLeftCorner(q, m);
}

// LAPACK dgeqp3 with every column free; at these sizes (min(q, m) below its crossover of 128)
// it runs the unblocked dlaqp2, which this follows: pivot on the largest remaining column
// norm (the first one on ties), reflect, and downdate the norms, recomputing a norm when
// cancellation has eaten more than √ε of it.
void PivotedQr::factor(double rank_tol) {
  const Index q = q_, m = m_;
  k_ = std::min(q, m);
  if (piv_.size() < m) piv_.resize(m);
  if (tau_.size() < k_) tau_.resize(k_);
  if (vn1_.size() < m) {
    vn1_.resize(m);
    vn2_.resize(m);
  }
  if (work_.size() < m) work_.resize(m);
  for (Index j = 0; j < m; ++j) piv_[j] = static_cast<int>(j);
  rank_ = 0;
  if (k_ == 0) return;
  auto H = h_.topLeftCorner(q, m);
  for (Index j = 0; j < m; ++j) vn1_[j] = vn2_[j] = H.col(j).norm();
  const double tol3z = std::sqrt(std::numeric_limits<double>::epsilon());
  for (Index i = 0; i < k_; ++i) {
    Index pvt = i;
    for (Index j = i + 1; j < m; ++j)
      if (vn1_[j] > vn1_[pvt]) pvt = j;
    if (pvt != i) {
      H.col(pvt).swap(H.col(i));
      std::swap(piv_[pvt], piv_[i]);
      vn1_[pvt] = vn1_[i];
      vn2_[pvt] = vn2_[i];
    }
    double tau = 0.0, beta = 0.0;
    H.col(i).tail(q - i).makeHouseholderInPlace(tau, beta);
    H(i, i) = beta;
    tau_[i] = tau;
    if (i + 1 < m)
      H.block(i, i + 1, q - i, m - i - 1)
          .applyHouseholderOnTheLeft(H.col(i).tail(q - i - 1), tau, work_.data());
    for (Index j = i + 1; j < m; ++j) {
      if (vn1_[j] == 0.0) continue;
      const double a = std::abs(H(i, j)) / vn1_[j];
      const double temp = std::max(0.0, 1.0 - a * a);
      const double ratio = vn1_[j] / vn2_[j];
      if (temp * ratio * ratio <= tol3z) {
        vn1_[j] = i + 1 < q ? H.col(j).tail(q - i - 1).norm() : 0.0;
        vn2_[j] = vn1_[j];
      } else {
        vn1_[j] *= std::sqrt(temp);
      }
    }
  }
  for (Index i = 0; i < k_; ++i)
    if (std::abs(H(i, i)) > rank_tol) ++rank_;
}

// -- Least squares on a factorisation (mirror of ls_coefficients / min_norm_lsq)

// K = aux_[:rows, :cols] (rows ≥ cols) and its right-hand side auxr_[:rows]: Householder QR of
// K applied to the right-hand side, then w_[:size] = R⁻¹ (Qᵀ rhs)[:size] (size = cols); the
// reference's scipy.linalg.qr (economic) and trtrs.
bool HlsSolver::lstsq_qr(Index rows, Index cols, Index size) {
  auto K = aux_.view(rows, cols);
  auto rhs = head_of(auxr_, rows);
  if (work_.size() < cols) work_.resize(cols);
  for (Index i = 0; i < cols; ++i) {
    double tau = 0.0, beta = 0.0;
    K.col(i).tail(rows - i).makeHouseholderInPlace(tau, beta);
    K(i, i) = beta;
    const auto v = K.col(i).tail(rows - i - 1);
    if (i + 1 < cols)
      K.block(i, i + 1, rows - i, cols - i - 1).applyHouseholderOnTheLeft(v, tau, work_.data());
    rhs.tail(rows - i).applyHouseholderOnTheLeft(v, tau, work_.data());
  }
  if (const Index info = zero_on_diagonal(K, size)) return fail(singular(info));
  auto w = head_of(w_, size);
  w = rhs.head(size);
  K.topLeftCorner(size, size).triangularView<Eigen::Upper>().solveInPlace(w);
  return true;
}

// Coefficients w_[:size] of the (damped) min-norm least-squares solution u = Q[:, :size] w of
// M u ≈ r, from the factorisation fac of Mᵀ (q, m): rank-truncated when undamped, through the
// QR of the small augmented matrix [Rᵀ; k I] when damped (the paper's regularised system
// restricted to the row space of M).
bool HlsSolver::ls_coefficients(const PivotedQr& fac, const Eigen::Ref<const Vector>& r,
                                double k, Index& size) {
  const Index m = fac.cols();
  const auto h = fac.h();
  if (k == 0.0) {
    const Index rr = fac.rank();
    size = rr;
    if (rr == 0) return true;
    if (rr == m) {
      auto w = head_of(w_, rr);
      for (Index i = 0; i < m; ++i) w[i] = r[fac.piv(i)];
      h.topLeftCorner(rr, rr).triangularView<Eigen::Upper>().transpose().solveInPlace(w);
      return true;
    }
    // dependent rows (a conflicting level): least squares in the rank-rr factor
    auto K = aux_.view(m, rr);
    K.setZero();
    for (Index i = 0; i < rr; ++i) K.col(i).segment(i, m - i) = h.row(i).tail(m - i).transpose();
    auto rhs = head_of(auxr_, m);
    for (Index i = 0; i < m; ++i) rhs[i] = r[fac.piv(i)];
    return lstsq_qr(m, rr, rr);
  }
  const Index s = fac.size();
  size = s;
  if (s == 0) return true;
  auto K = aux_.view(m + s, s);
  K.setZero();
  for (Index i = 0; i < s; ++i) K.col(i).segment(i, m - i) = h.row(i).tail(m - i).transpose();
  K.bottomRows(s).diagonal().setConstant(k);
  auto rhs = head_of(auxr_, m + s);
  for (Index i = 0; i < m; ++i) rhs[i] = r[fac.piv(i)];
  rhs.tail(s).setZero();
  return lstsq_qr(m + s, s, s);
}

// -- Primal active set (mirror of active_set_lsq)

// N (q, q − rank): orthonormal basis of the null space of the working rows P[working], and
// their QR in face_.
void HlsSolver::face_basis(Index q, Index mi, double rank_tol) {
  const auto P = P_.view(mi, q);
  const Index nw = static_cast<Index>(working_.size());
  auto GWt = face_.load(q, nw);
  for (Index j = 0; j < nw; ++j) GWt.col(j) = P.row(working_[j]).transpose();
  face_.factor(rank_tol);
  ndim_ = q - face_.rank();
  auto N = N_.view(q, ndim_);
  N.setZero();
  for (Index j = 0; j < ndim_; ++j) N(face_.rank() + j, j) = 1.0;
  face_.apply_left(N, false);
}

// lam_[:nw] solving P_Wᵀ λ = −grad by the QR of P_Wᵀ (the working rows are independent).
bool HlsSolver::multipliers(Index q) {
  const Index nw = static_cast<Index>(working_.size());
  auto rhs = head_of(rhs_, q);
  rhs = -grad_.head(q);
  face_.apply_left(rhs, true);
  const auto h = face_.h();
  if (const Index info = zero_on_diagonal(h, nw)) return fail(singular(info));
  h.topLeftCorner(nw, nw).triangularView<Eigen::Upper>().solveInPlace(rhs.head(nw));
  auto lam = head_of(lam_, nw);
  for (Index i = 0; i < nw; ++i) lam[face_.piv(i)] = rhs[i];
  return true;
}

// min ½‖F z − g‖² + ½k²‖z‖² s.t. P z ≤ hp from the feasible z_[:q]; F = F_[:m, :q],
// P = P_[:mi, :q], g = g_[:m], hp = hp_[:mi]. Leaves the solution in z_, the final working set
// in working_ (the order rows were added), their multipliers in lam_ and the rows with a
// clearly positive multiplier in saturated_ (working order).
bool HlsSolver::active_set(Index m, Index q, Index mi, double k, const HlsOptions& o,
                           int& iterations) {
  const auto F = F_.view(m, q);
  const auto P = P_.view(mi, q);
  const auto g = g_.head(m);
  const auto hp = hp_.head(mi);
  auto z = head_of(z_, q);
  working_.clear();
  saturated_.clear();
  in_working_.assign(mi, 0);
  N_.view(q, q);
  auto rowsum = head_of(rowsum_, mi);
  rowsum = P.cwiseAbs().rowwise().sum();
  const int max_iter = o.max_iter > 0 ? o.max_iter : static_cast<int>(10 * (q + mi) + 10);
  face_basis(q, mi, o.rank_tol);
  for (int it = 1; it <= max_iter; ++it) {
    const auto N = N_.view(q, ndim_);
    // The damping acts on z + N u; with v = u + Nᵀz it becomes a plain damped problem in v.
    auto shift = head_of(shift_, ndim_);
    if (k > 0.0) {
      shift.noalias() = N.transpose() * z;  // then negated: a negated product needs a temporary
      shift = -shift;
    } else {
      shift.setZero();
    }
    auto Mt = ls_.load(ndim_, m);  // Mᵀ = (F N)ᵀ; a few rows: no GEMM blocking
    Mt.noalias() = N.transpose().lazyProduct(F.transpose());
    auto r = head_of(r_, m);
    r = g;
    r.noalias() -= F * z;
    r.noalias() -= Mt.transpose() * shift;
    ls_.factor(o.rank_tol);
    Index size = 0;
    if (!ls_coefficients(ls_, r, k, size)) return false;
    auto v = head_of(v_, ndim_);
    v.setZero();
    v.head(size) = w_.head(size);
    ls_.apply_left(v, false);
    v += shift;
    auto p = head_of(step_, q);
    p.noalias() = N * v;
    const double pnorm = p.norm();
    if (pnorm > 1e-13 * (1.0 + z.norm())) {
      auto Pp = head_of(Pp_, mi);
      Pp.noalias() = P * p;
      auto Pz = head_of(Pz_, mi);
      Pz.noalias() = P * z;
      Index j = -1;
      double alpha = 1.0, best = std::numeric_limits<double>::infinity();
      for (Index i = 0; i < mi; ++i) {
        if (in_working_[i] || !(Pp[i] > 1e-12 * (1.0 + rowsum[i] * pnorm))) continue;
        const double ratio = std::max(hp[i] - Pz[i], 0.0) / Pp[i];
        if (ratio < best) {
          best = ratio;
          j = i;
        }
      }
      if (j >= 0 && best < 1.0)
        alpha = best;
      else
        j = -1;
      z += alpha * p;
      if (j >= 0) {
        working_.push_back(static_cast<int>(j));
        in_working_[j] = 1;
        face_basis(q, mi, o.rank_tol);
        continue;
      }
    }
    // at the minimiser of the current face: optimal unless a multiplier has the wrong sign
    if (working_.empty()) {
      iterations = it;
      return true;
    }
    auto grad = head_of(grad_, q);
    auto res = head_of(r_, m);
    res.noalias() = F * z;
    res -= g;
    grad.noalias() = F.transpose() * res;
    grad += k * k * z;
    if (!multipliers(q)) return false;
    const Index nw = static_cast<Index>(working_.size());
    const auto lam = lam_.head(nw);
    Index worst = 0;
    for (Index i = 1; i < nw; ++i)
      if (lam[i] < lam[worst]) worst = i;
    const double lam_tol = 1e-10 * (1.0 + grad.cwiseAbs().maxCoeff());
    if (lam[worst] >= -lam_tol) {
      for (Index i = 0; i < nw; ++i)
        if (lam[i] > lam_tol) saturated_.push_back(working_[i]);
      iterations = it;
      return true;
    }
    in_working_[working_[worst]] = 0;
    working_.erase(working_.begin() + worst);
    face_basis(q, mi, o.rank_tol);
  }
  return fail("active set did not converge in " + std::to_string(max_iter) + " iterations");
}

// -- The hierarchy (mirror of solve_hls)

bool HlsSolver::fail(const std::string& message) {
  message_ = message;
  return false;
}

// Z ← (Z Q)[:, rank:], Q from fac (a factorisation in the reduced coordinates of Z)
void HlsSolver::null_basis(PivotedQr& fac) {
  fac.apply_right(Zb_.middleCols(z0_, p_));
  z0_ += fac.rank();
  p_ -= fac.rank();
}

// Closed-form level (§II-B/C); rank: the rank used.
bool HlsSolver::equality_level(const HlsLevel& lv, double rank_tol, int& rank) {
  const Index m = lv.has_task ? lv.A.rows() : 0;
  rank = 0;
  if (p_ == 0 || m == 0) return true;
  const auto Z = Zb_.middleCols(z0_, p_);
  auto Ft = ls_.load(p_, m);  // (A Z)ᵀ
  Ft.noalias() = Z.transpose() * lv.A.transpose();
  auto r = head_of(r_, m);
  r = lv.b;
  r.noalias() -= lv.A * x_;
  ls_.factor(rank_tol);
  Index size = 0;
  if (!ls_coefficients(ls_, r, lv.damping, size)) return false;
  // One application of Q to Z gives both the step (leading columns) and the next basis.
  ls_.apply_right(Zb_.middleCols(z0_, p_));
  x_.noalias() += Zb_.middleCols(z0_, size) * w_.head(size);
  rank = static_cast<int>(ls_.rank());
  z0_ += rank;
  p_ -= rank;
  return true;
}

// Phase 1: min ‖w‖² s.t. l ≤ C (x + Z y) − w ≤ u, earlier inequalities kept. Leaves
// y = z_[:p], w = z_[p : p + mc].
bool HlsSolver::least_violation(const HlsLevel& lv, const HlsOptions& o, int& iterations) {
  const Index p = p_, mc = lv.C.rows(), n = n_;
  const auto Z = Zb_.middleCols(z0_, p);
  const auto Cx = Cx_.head(mc);
  Index n_up = 0, n_dn = 0;
  for (Index i = 0; i < mc; ++i) {
    n_up += std::isfinite(lv.u[i]);
    n_dn += std::isfinite(lv.l[i]);
  }
  const Index mi = n_up + n_dn + mi_;
  auto P = P_.view(mi, p + mc);
  auto hp = head_of(hp_, mi);
  P.setZero();
  Index row = 0;
  for (Index i = 0; i < mc; ++i) {
    if (!std::isfinite(lv.u[i])) continue;
    P.row(row).head(p).noalias() = lv.C.row(i) * Z;
    P(row, p + i) = -1.0;
    hp[row++] = lv.u[i] - Cx[i];
  }
  for (Index i = 0; i < mc; ++i) {
    if (!std::isfinite(lv.l[i])) continue;
    P.row(row).head(p).noalias() = lv.C.row(i) * Z;
    P.row(row).head(p) *= -1.0;
    P(row, p + i) = 1.0;
    hp[row++] = Cx[i] - lv.l[i];
  }
  const auto G = G_.view(mi_, n);
  P.bottomLeftCorner(mi_, p).noalias() = G * Z;
  hp.tail(mi_) = h_.head(mi_);
  hp.tail(mi_).noalias() -= G * x_;
  auto F = F_.view(mc, p + mc);
  F.setZero();
  F.rightCols(mc).setIdentity();
  head_of(g_, mc).setZero();
  auto z = head_of(z_, p + mc);
  z.head(p).setZero();
  for (Index i = 0; i < mc; ++i) z[p + i] = Cx[i] - std::clamp(Cx[i], lv.l[i], lv.u[i]);
  return active_set(mc, p + mc, mi, 0.0, o, iterations);
}

// A level with inequalities (its own or inherited), §III-B.
bool HlsSolver::inequality_level(const HlsLevel& lv, const HlsOptions& o, HlsLevelStats& st) {
  const Index n = n_;
  int iterations = 0, n_held = 0;
  double violation = 0.0;
  kept_.clear();
  if (lv.has_ineq) {
    const Index mc = lv.C.rows();
    auto Cx = head_of(Cx_, mc);
    Cx.noalias() = lv.C * x_;
    auto lo = head_of(lo_, mc);
    auto hi = head_of(hi_, mc);
    lo = lv.l;
    hi = lv.u;
    bool violated = false;
    for (Index i = 0; i < mc; ++i)
      violated = violated || Cx[i] - hi[i] > o.feas_tol || lo[i] - Cx[i] > o.feas_tol;
    if (violated) {
      int it = 0;
      if (!least_violation(lv, o, it)) return false;
      iterations += it;
      const Index p = p_;
      x_.noalias() += Zb_.middleCols(z0_, p) * z_.head(p);
      const auto w = z_.segment(p, mc);
      violation = w.norm();
      // Rows held at their least violation are equalities from here on (§III-B).
      for (Index i = 0; i < mc; ++i) n_held += std::abs(w[i]) > o.feas_tol;
      auto Ht = basis_.load(p, n_held);  // (C[held] Z)ᵀ
      Index col = 0;
      for (Index i = 0; i < mc; ++i) {
        if (std::abs(w[i]) > o.feas_tol) {
          Ht.col(col++).noalias() = Zb_.middleCols(z0_, p).transpose() * lv.C.row(i).transpose();
        } else {
          kept_.push_back(static_cast<int>(i));
        }
        lo[i] += std::min(w[i], 0.0);
        hi[i] += std::max(w[i], 0.0);
      }
      basis_.factor(o.rank_tol);
      null_basis(basis_);
    } else {
      for (Index i = 0; i < mc; ++i) kept_.push_back(static_cast<int>(i));
    }
  }
  // G ← [G; C[up]; −C[dn]] (the level's own rows, one-sided)
  Index mi = mi_;
  for (const int i : kept_) mi += std::isfinite(hi_[i]);
  for (const int i : kept_) mi += std::isfinite(lo_[i]);
  {
    auto G = G_.view(mi, n);
    auto h = head_of(h_, mi);
    Index row = mi_;
    for (const int i : kept_) {
      if (!std::isfinite(hi_[i])) continue;
      G.row(row) = lv.C.row(i);
      h[row++] = hi_[i];
    }
    for (const int i : kept_) {
      if (!std::isfinite(lo_[i])) continue;
      G.row(row) = -lv.C.row(i);
      h[row++] = -lo_[i];
    }
  }
  const Index p = p_, m = lv.has_task ? lv.A.rows() : 0;
  const auto Z = Zb_.middleCols(z0_, p);
  const auto G = G_.view(mi, n);
  P_.view(mi, p).noalias() = G * Z;
  auto hp = head_of(hp_, mi);
  hp = h_.head(mi);
  hp.noalias() -= G * x_;
  auto g = head_of(g_, m);
  auto F = F_.view(m, p);
  if (m > 0) {
    F.noalias() = lv.A * Z;
    g = lv.b;
    g.noalias() -= lv.A * x_;
  }
  head_of(z_, p).setZero();
  int it = 0;
  if (!active_set(m, p, mi, lv.damping, o, it)) return false;
  x_.noalias() += Z * z_.head(p);
  // Non-regularised factorisation of [C_sat; A] in reduced coordinates gives the next basis.
  const Index ns = static_cast<Index>(saturated_.size());
  {
    const auto Pz = P_.view(mi, p);
    auto Ht = basis_.load(p, ns + m);
    for (Index j = 0; j < ns; ++j) Ht.col(j) = Pz.row(saturated_[j]).transpose();
    Ht.rightCols(m) = F_.view(m, p).transpose();
  }
  basis_.factor(o.rank_tol);
  null_basis(basis_);
  // the saturated rows leave the free inequalities (order kept)
  in_working_.assign(mi, 0);
  for (const int i : saturated_) in_working_[i] = 1;
  auto Gall = G_.view(mi, n);
  Index row = 0;
  for (Index i = 0; i < mi; ++i) {
    if (in_working_[i]) continue;
    if (row != i) {
      Gall.row(row) = Gall.row(i);
      h_[row] = h_[i];
    }
    ++row;
  }
  mi_ = row;
  st.iterations = iterations + it;
  st.n_active = static_cast<int>(working_.size()) + n_held;
  st.n_saturated = static_cast<int>(ns) + n_held;
  st.violation = violation;
  return true;
}

// ‖A x − b‖ at the current x (0 without a task)
double HlsSolver::residual(const HlsLevel& lv) {
  if (!lv.has_task) return 0.0;
  auto r = head_of(r_, lv.A.rows());
  r.noalias() = lv.A * x_;
  r -= lv.b;
  return r.norm();
}

HlsLevelStats& HlsSolver::next_stats(std::size_t i) {
  if (stats_.size() <= i) stats_.resize(i + 1);
  HlsLevelStats& st = stats_[i];
  st.iterations = st.n_active = st.n_saturated = st.rank = 0;
  st.residual = st.violation = 0.0;
  return st;
}

bool HlsSolver::reduced_qr(const HlsOptions& o) {
  const Index n = n_;
  Zb_.setIdentity(n, n);
  z0_ = 0;
  p_ = n;
  mi_ = 0;
  for (std::size_t i = 0; i < levels_.size(); ++i) {
    const HlsLevel& lv = levels_[i];
    const auto t0 = Clock::now();
    HlsLevelStats& st = next_stats(i);
    const Index p_in = p_;
    if (!lv.has_ineq && mi_ == 0) {
      if (!equality_level(lv, o.rank_tol, st.rank)) return false;
    } else {
      if (!inequality_level(lv, o, st)) return false;
      st.rank = static_cast<int>(p_in - p_);
    }
    st.time = seconds_since(t0);
    st.residual = residual(lv);
    st.dof_left = static_cast<int>(p_);
    st.x = x_;
  }
  return true;
}

// -- Entry points

void HlsSolver::resize(int n_levels, int n) {
  levels_.resize(n_levels);
  n_ = n;
}

bool HlsSolver::solve(HlsAlgorithm algorithm, const Eigen::Ref<const Vector>& x0,
                      const HlsOptions& options) {
  const auto t0 = Clock::now();
  message_.clear();
  x_ = x0;
  if (stats_.size() > levels_.size()) stats_.resize(levels_.size());
  bool ok = false;
  if (algorithm == HlsAlgorithm::kReducedQr) {
    ok = reduced_qr(options);
  } else {
    for (std::size_t i = 0; i < levels_.size(); ++i) {
      const HlsLevel& lv = levels_[i];
      if (lv.has_ineq || !lv.has_task)
        return fail("level " + (lv.name.empty() ? std::to_string(i) : lv.name) +
                    ": the SVD / full-QR baselines take equality-only levels");
    }
    ok = algorithm == HlsAlgorithm::kFullQr ? full_qr(options) : svd(options);
  }
  time_ = seconds_since(t0);
  return ok;
}

}  // namespace wbcbench
