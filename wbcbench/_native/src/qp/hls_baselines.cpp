// The two baselines of the RQR-HQP paper's Fig. 1 on the stack of an HlsSolver: the native
// mirror of wbcbench/qp/hls_baselines.py (the SVD task-priority algorithm and the QR algorithm
// in full coordinates); the pivoted QR and the damped least squares are those of qp/hls.cpp.
#include <chrono>

#include "qp/hls.hpp"

namespace wbcbench {

namespace {

using Index = Eigen::Index;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

// Level i factorises the stacked tasks above it, forms the projector P = Z Zᵀ on their null
// space and solves min ‖A P d − (b − A x)‖ (+ k²‖d‖²) in all n variables.
bool HlsSolver::full_qr(const HlsOptions& o) {
  const Index n = n_;
  Index above = 0;
  for (std::size_t i = 0; i < levels_.size(); ++i) {
    const HlsLevel& lv = levels_[i];
    const auto t0 = Clock::now();
    HlsLevelStats& st = next_stats(i);
    const Index m = lv.A.rows();
    auto St = basis_.load(n, above);
    St = stacked_.view(n, above);
    basis_.factor(o.rank_tol);
    const Index r_above = basis_.rank();
    auto Z = basis_cols_.view(n, n - r_above);
    Z.setZero();
    for (Index j = 0; j < n - r_above; ++j) Z(r_above + j, j) = 1.0;
    basis_.apply_left(Z, false);
    auto P = proj_.view(n, n);
    P.noalias() = Z * Z.transpose();
    auto Mt = ls_.load(n, m);  // (A P)ᵀ
    Mt.noalias() = P.transpose() * lv.A.transpose();
    auto r = head_of(r_, m);
    r = lv.b;
    r.noalias() -= lv.A * x_;
    ls_.factor(o.rank_tol);
    Index size = 0;
    if (!ls_coefficients(ls_, r, lv.damping, size)) return false;
    auto d = head_of(v_, n);
    d.setZero();
    d.head(size) = w_.head(size);
    ls_.apply_left(d, false);
    x_ += d;
    auto S = stacked_.view(n, above + m);
    S.middleCols(above, m) = lv.A.transpose();
    above += m;
    st.time = seconds_since(t0);
    st.residual = residual(lv);
    st.rank = static_cast<int>(ls_.rank());
    st.dof_left = static_cast<int>(n - r_above - ls_.rank());
    st.x = x_;
  }
  return true;
}

// The classical task-priority algorithm: x += (A P)⁺ (b − A x), P −= (A P)⁺ (A P), by SVD;
// damped, σ / (σ² + k²) on every singular value for the step, the truncated pseudo-inverse for
// the projector.
bool HlsSolver::svd(const HlsOptions& o) {
  const Index n = n_;
  auto P = proj_.view(n, n);
  P.setIdentity();
  Index dof = n;
  const unsigned options = Eigen::ComputeThinU | Eigen::ComputeThinV;
  if (svd_.size() < levels_.size()) {
    svd_.resize(levels_.size());
    svd_in_.resize(levels_.size());
  }
  for (std::size_t i = 0; i < levels_.size(); ++i) {
    const HlsLevel& lv = levels_[i];
    const auto t0 = Clock::now();
    HlsLevelStats& st = next_stats(i);
    const Index m = lv.A.rows();
    Matrix& M = svd_in_[i];  // JacobiSVD takes a plain matrix
    M.resize(m, n);
    M.noalias() = lv.A * P;
    Eigen::JacobiSVD<Matrix>& dec = svd_[i];
    if (dec.rows() != m || dec.cols() != n) dec = Eigen::JacobiSVD<Matrix>(m, n, options);
    dec.compute(M, options);
    const auto& s = dec.singularValues();
    const Index ns = s.size();
    Index r = 0;
    while (r < ns && s[r] > o.rank_tol) ++r;
    auto res = head_of(r_, m);
    res = lv.b;
    res.noalias() -= lv.A * x_;
    auto c = head_of(v_, ns);
    c.noalias() = dec.matrixU().transpose() * res;
    const double k = lv.damping;
    if (k > 0.0) {
      c.array() *= s.array() / (s.array().square() + k * k);
      x_.noalias() += dec.matrixV() * c;
    } else {
      auto cr = c.head(r);
      cr.array() /= s.head(r).array();
      x_.noalias() += dec.matrixV().leftCols(r) * cr;
    }
    P.noalias() -= dec.matrixV().leftCols(r) * dec.matrixV().leftCols(r).transpose();
    dof -= r;
    st.time = seconds_since(t0);
    st.residual = residual(lv);
    st.rank = static_cast<int>(r);
    st.dof_left = static_cast<int>(dof);
    st.x = x_;
  }
  return true;
}

}  // namespace wbcbench
