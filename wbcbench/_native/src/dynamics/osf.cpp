#include "dynamics/osf.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <chrono>
#include <stdexcept>

namespace wbcbench {

namespace {

// Numerical rank from a non-increasing vector (an expression) of |R_ii| or singular values.
template <typename Diag>
int rank_of(const Eigen::MatrixBase<Diag>& diag, double rcond, double scale = 0.0) {
  if (diag.size() == 0 || diag(0) <= 0.0) return 0;
  const double cut = rcond * std::max(diag(0), scale);
  return static_cast<int>((diag.array() > cut).count());
}

// out = A⁻¹ of a symmetric positive definite A by Cholesky (factor kept in llt); false if it is
// not positive definite. Allocates nothing once llt and out have A's shape.
bool spd_inverse(const Matrix& A, Eigen::LLT<Matrix>& llt, Matrix& out) {
  llt.compute(A);
  if (llt.info() != Eigen::Success) return false;
  out.setIdentity(A.rows(), A.cols());
  llt.solveInPlace(out);
  return true;
}

// A = 0.5 (A + Aᵀ) in place (the same values as the expression, without its temporary).
void symmetrize(Matrix& A) {
  for (Eigen::Index j = 0; j < A.cols(); ++j) {
    for (Eigen::Index i = j + 1; i < A.rows(); ++i) {
      const double s = 0.5 * (A(i, j) + A(j, i));
      A(i, j) = s;
      A(j, i) = s;
    }
  }
}

}  // namespace

void Cod::compute(const Matrix& Y, double rcond, Decomposition& d) {
  const Eigen::Index k = Y.rows(), n = Y.cols();
  qr_.compute(Y);
  const int r = rank_of(qr_.matrixQR().diagonal().cwiseAbs(), rcond);
  // Q (k, k) whole: Q₁ enters Y†, Q₂ is the left null space. The sequence is formed in place
  // with our workspace, one per length (HouseholderSequence::evalTo resizes it, and without it
  // allocates one).
  Q_.resize(k, k);
  qr_.householderQ().evalTo(Q_, work_q_);
  // [R11 R12]ᵀ (n, r) = Z [T'; 0]: Y P = Q₁ T'ᵀ Z₁ᵀ
  trap_ = qr_.matrixQR().topRows(r).transpose();
  trap_.triangularView<Eigen::StrictlyUpper>().setZero();
  qz_.compute(trap_);
  Z_.resize(n, n);
  qz_.householderQ().evalTo(Z_, work_z_);
  d.rank = r;
  // Y† = P Z₁ T'⁻ᵀ Q₁ᵀ, v₂ = P Z₂ (V = P Z without forming it)
  const auto T = qz_.matrixQR().topRows(r).triangularView<Eigen::Upper>();
  q1t_ = Q_.leftCols(r).transpose();
  T.transpose().solveInPlace(q1t_);
  Zq_.noalias() = Z_.leftCols(r) * q1t_;
  d.pinv.resize(n, k);
  d.right_null.resize(n, n - r);
  const auto& perm = qr_.colsPermutation().indices();
  for (Eigen::Index i = 0; i < n; ++i) {
    d.pinv.row(perm(i)) = Zq_.row(i);
    d.right_null.row(perm(i)) = Z_.row(i).tail(n - r);
  }
  d.left_null = Q_.rightCols(k - r);
}

Decomposition svd(const Matrix& Y, double rcond) {
  const Eigen::Index k = Y.rows(), n = Y.cols();
  Eigen::BDCSVD<Matrix> s(Y, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Vector& sv = s.singularValues();
  const int r = rank_of(sv, rcond);
  Decomposition d;
  d.rank = r;
  d.pinv.noalias() = s.matrixV().leftCols(r) * sv.head(r).cwiseInverse().asDiagonal() *
                     s.matrixU().leftCols(r).transpose();
  d.right_null = s.matrixV().rightCols(n - r);
  d.left_null = s.matrixU().rightCols(k - r);
  return d;
}

int PsdPinv::compute(const Matrix& X, bool by_svd, double rcond, double scale, Matrix& out) {
  const Eigen::Index m = X.rows();
  out.setZero(m, m);
  if (m == 0) return 0;
  if (by_svd) {
    Eigen::BDCSVD<Matrix> s(X, Eigen::ComputeFullU);
    const int r = rank_of(s.singularValues(), rcond, scale);
    const auto U = s.matrixU().leftCols(r);
    out.noalias() = U * s.singularValues().head(r).cwiseInverse().asDiagonal() * U.transpose();
    return r;
  }
  qr_.compute(X);
  const int r = rank_of(qr_.matrixQR().diagonal().cwiseAbs(), rcond, scale);
  if (r == 0) return 0;
  if (r == m && spd_inverse(X, llt_, out)) return r;
  // X = Q₁ C Q₁ᵀ with C = Q₁ᵀ X Q₁ positive definite: X⁺ = Q₁ C⁻¹ Q₁ᵀ
  Q1_.setIdentity(m, r);
  qr_.householderQ().applyThisOnTheLeft(Q1_, work_);  // the first r columns of Q only
  XQ1_.noalias() = X * Q1_;
  C_.noalias() = Q1_.transpose() * XQ1_;
  llt_.compute(C_);
  if (llt_.info() != Eigen::Success) throw std::runtime_error("psd_pinv: range block not SPD");
  S_ = Q1_.transpose();
  llt_.solveInPlace(S_);
  out.noalias() = Q1_ * S_;
  return r;
}

void OsfParams::level_step(int i, const Vector& prev, const Eigen::Ref<const Vector>& ref,
                           Vector& out, Eigen::Ref<Vector> work) const {
  const LevelParams& lv = levels[i];
  out = prev;
  out.noalias() += lv.E * ref;
  out.noalias() -= lv.B * lv.bias;
  if (exact) {
    work.noalias() = lv.Jhat * prev;
    out.noalias() -= lv.B * work;
  }
}

void OsfModel::compute(const RobotDynamics& dyn, const Matrix& J, const Vector& drift, long tick,
                       OsfParams& p) {
  const auto t0 = std::chrono::steady_clock::now();
  const Matrix& Minv = dyn.Minv();
  const Matrix& M = dyn.M();
  const Vector& h = dyn.h();
  const Matrix& Jc = dyn.contact_jacobian();
  const Vector& dJc = dyn.contact_drift();
  const Eigen::Index n = dyn.nv(), k = n - 6, c = Jc.rows();

  // -- contact-constrained dynamics
  Matrix& Phi = Phi_;
  Matrix& Y = Y_;
  Phi = Minv;
  if (c == 0) {
    Y.setZero(k, n);
    Y.rightCols(k).setIdentity();
    p.qdd0.noalias() = -Minv * h;
    p.F.setZero(0, k);
    p.f0.setZero(0);
  } else {
    Bc_.noalias() = Minv * Jc.transpose();  // (n, c)
    JcB_.noalias() = Jc * Bc_;
    // redundant contacts (several points on one frame: by construction) by the SVD
    if (dyn.contact_rows_redundant() || !spd_inverse(JcB_, llt_c_, Lc_)) {
      psd_c_.compute(JcB_, true, 1e-9, 0.0, Lc_);
    }
    Xt_.noalias() = Lc_ * Bc_.transpose();  // J̄_cᵀ (c, n)
    Phi.noalias() -= Bc_ * Xt_;
    symmetrize(Phi);
    Y.noalias() = -Xt_.rightCols(k).transpose() * Jc;
    Y.rightCols(k).diagonal().array() += 1.0;
    p.qdd0.noalias() = -Phi * h;
    p.qdd0.noalias() -= Xt_.transpose() * dJc;
    p.F = -Xt_.rightCols(k);
    p.f0.noalias() = Xt_ * h;
    p.f0.noalias() -= Lc_ * dJc;
  }
  p.W = Phi.bottomRightCorner(k, k);
  p.Phi_a = Phi.rightCols(k);

  // -- the dynamically consistent inverse Ȳ and N_w
  if (spec_.inverse == OsfInverse::kSvd) {
    dec_ = svd(Y, spec_.rcond);
  } else {
    cod_.compute(Y, spec_.rcond, dec_);
  }
  Matrix& Ybar = Ybar_;
  Ybar = dec_.pinv;
  if (spec_.inverse != OsfInverse::kPinv && dec_.right_null.cols() > 0) {
    const Matrix& v2 = dec_.right_null;
    Mv2_.noalias() = M * v2;
    vMv_.noalias() = v2.transpose() * Mv2_;
    llt_v_.compute(vMv_);
    if (llt_v_.info() != Eigen::Success) throw std::runtime_error("osf: v₂ᵀ M v₂ not SPD");
    alpha_.noalias() = Mv2_.transpose() * dec_.pinv;  // eq. 19
    llt_v_.solveInPlace(alpha_);
    Ybar.noalias() -= v2 * alpha_;
  }
  p.Nw = dec_.left_null;

  // -- the levels: the products with every task row at once (fewer, larger GEMMs)
  const int L = static_cast<int>(spec_.level_dims.size());
  p.levels.resize(L);
  lw_.resize(L);
  p.exact = spec_.exact;
  Matrix& N = N_;
  JPhi_.noalias() = J * p.Phi_a;
  JY_.noalias() = J * Ybar;
  JMinv_.noalias() = J * Minv;
  // each row's inverse inertia without contacts or levels above sets its level's rank scale
  inertia_ = JMinv_.cwiseProduct(J).rowwise().sum();
  Eigen::Index row = 0;
  for (int i = 0; i < L; ++i) {
    const Eigen::Index m = spec_.level_dims[i];
    LevelParams& lv = p.levels[i];
    LevelWork& w = lw_[i];
    Matrix &a = w.a, &aW = w.aW, &X = w.X, &Jbar = w.Jbar;
    lv.Jhat = JPhi_.middleRows(row, m);
    lv.bias = drift.segment(row, m);
    lv.bias.noalias() += J.middleRows(row, m) * p.qdd0;
    if (i == 0) {
      a = JY_.middleRows(row, m);
    } else {
      a.noalias() = JY_.middleRows(row, m) * N;
    }
    aW.noalias() = a * p.W;
    X.noalias() = aW * a.transpose();
    const double scale = m ? inertia_.segment(row, m).maxCoeff() : 0.0;
    symmetrize(X);
    w.psd.compute(X, spec_.inverse == OsfInverse::kSvd, spec_.rcond, scale, lv.Lam);
    lv.Jstar = a;
    lv.B.noalias() = a.transpose() * lv.Lam;
    if (spec_.force_level[i]) {
      lv.E = a.transpose();
    } else {
      lv.E = lv.B;
    }
    if (i + 1 < L) {
      // J̄ = W B = (a W)ᵀ Λ: W is symmetric, and a W is at hand
      Jbar.noalias() = aW.transpose() * lv.Lam;
      if (i == 0) {
        N.noalias() = -Jbar * a;
        N.diagonal().array() += 1.0;
      } else {
        w.NJ.noalias() = N * Jbar;
        N.noalias() -= w.NJ * a;
      }
    }
    row += m;
  }

  // -- the wrench distribution: F N_w = Q_f R_f, Y_c = N_w R_f⁻¹
  const Eigen::Index np = p.Nw.cols();
  if (np == 0) {
    p.Yc.setZero(k, 0);
    p.Qf.setZero(c, 0);
  } else {
    FNw_.noalias() = p.F * p.Nw;
    qr_f_.compute(FNw_);
    p.Qf.setIdentity(c, np);
    qr_f_.householderQ().applyThisOnTheLeft(p.Qf, work_);  // the first np columns of Q only
    const auto Rf = qr_f_.matrixQR().topRows(np).triangularView<Eigen::Upper>();
    YcT_ = p.Nw.transpose();
    Rf.transpose().solveInPlace(YcT_);
    p.Yc = YcT_.transpose();
  }
  p.Yw.noalias() = p.Yc * p.Qf.transpose();
  p.G = Jc.leftCols(6).transpose();

  // -- Γ = K ρ + γ₀ over all levels
  Eigen::Index total = 0;
  for (int m : spec_.level_dims) total += m;
  p.K.setZero(k, spec_.affine ? total : 0);
  p.gamma0.setZero(k);
  if (spec_.affine) {
    Eigen::Index col = 0;
    for (int i = 0; i < L; ++i) {
      const LevelParams& lv = p.levels[i];
      LevelWork& w = lw_[i];
      const Eigen::Index m = spec_.level_dims[i];
      if (spec_.exact && col) {
        w.JK.noalias() = lv.Jhat * p.K.leftCols(col);
        p.K.leftCols(col).noalias() -= lv.B * w.JK;
        w.jg.noalias() = lv.Jhat * p.gamma0;
        p.gamma0.noalias() -= lv.B * w.jg;
      }
      p.K.middleCols(col, m) = lv.E;
      p.gamma0.noalias() -= lv.B * lv.bias;
      col += m;
    }
  }
  p.tick = tick;
  p.compute_time =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace wbcbench
