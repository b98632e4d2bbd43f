#include "dynamics/osf.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <chrono>
#include <stdexcept>

namespace wbcbench {

namespace {

// Numerical rank from a non-increasing vector of |R_ii| or singular values.
int rank_of(const Vector& diag, double rcond, double scale = 0.0) {
  if (diag.size() == 0 || diag(0) <= 0.0) return 0;
  const double cut = rcond * std::max(diag(0), scale);
  return static_cast<int>((diag.array() > cut).count());
}

// The inverse of a symmetric positive definite matrix by Cholesky; false if it is not.
bool spd_inverse(const Matrix& A, Matrix& out) {
  Eigen::LLT<Matrix> llt(A);
  if (llt.info() != Eigen::Success) return false;
  out = llt.solve(Matrix::Identity(A.rows(), A.cols()));
  return true;
}

}  // namespace

Decomposition cod(const Matrix& Y, double rcond) {
  const Eigen::Index k = Y.rows(), n = Y.cols();
  Eigen::ColPivHouseholderQR<Matrix> qr(Y);
  const Vector diag = qr.matrixQR().diagonal().cwiseAbs();
  const int r = rank_of(diag, rcond);
  const Matrix Q = qr.householderQ();  // (k, k)
  // [R11 R12] (r, n) = Z [T'; 0] transposed: Y P = Q₁ T'ᵀ Z₁ᵀ
  Matrix trap = qr.matrixQR().topRows(r);
  for (int i = 1; i < r; ++i) trap.row(i).head(i).setZero();
  Eigen::HouseholderQR<Matrix> qz(trap.transpose());
  const Matrix Z = qz.householderQ();  // (n, n)
  Matrix V(n, n);
  V = qr.colsPermutation() * Z;  // P Z
  Decomposition d;
  d.rank = r;
  // Y† = V₁ T'⁻ᵀ Q₁ᵀ
  const auto T = qz.matrixQR().topRows(r).triangularView<Eigen::Upper>();
  Matrix q1t = Q.leftCols(r).transpose();
  T.transpose().solveInPlace(q1t);
  d.pinv.noalias() = V.leftCols(r) * q1t;
  d.right_null = V.rightCols(n - r);
  d.left_null = Q.rightCols(k - r);
  return d;
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

int psd_pinv(const Matrix& X, bool by_svd, double rcond, double scale, Matrix& out) {
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
  Eigen::ColPivHouseholderQR<Matrix> qr(X);
  const int r = rank_of(qr.matrixQR().diagonal().cwiseAbs(), rcond, scale);
  if (r == 0) return 0;
  if (r == m && spd_inverse(X, out)) return r;
  // X = Q₁ C Q₁ᵀ with C = Q₁ᵀ X Q₁ positive definite: X⁺ = Q₁ C⁻¹ Q₁ᵀ
  Matrix Q1 = Matrix::Identity(m, r);
  Q1.applyOnTheLeft(qr.householderQ());  // the first r columns of Q only
  const Matrix XQ1 = X * Q1;
  Eigen::LLT<Matrix> llt(Q1.transpose() * XQ1);
  if (llt.info() != Eigen::Success) throw std::runtime_error("psd_pinv: range block not SPD");
  Matrix S = Q1.transpose();
  llt.solveInPlace(S);
  out.noalias() = Q1 * S;
  return r;
}

void OsfParams::level_step(int i, const Vector& prev, const Eigen::Ref<const Vector>& ref,
                           Vector& out) const {
  const LevelParams& lv = levels[i];
  out = prev;
  out.noalias() += lv.E * ref;
  out.noalias() -= lv.B * lv.bias;
  if (exact) {
    const Vector jp = lv.Jhat * prev;
    out.noalias() -= lv.B * jp;
  }
}

void OsfModel::compute(const RobotDynamics& dyn, const Matrix& J, const Vector& drift, long tick,
                       OsfParams& p) const {
  const auto t0 = std::chrono::steady_clock::now();
  const Matrix& Minv = dyn.Minv();
  const Matrix& M = dyn.M();
  const Vector& h = dyn.h();
  const Matrix& Jc = dyn.contact_jacobian();
  const Vector& dJc = dyn.contact_drift();
  const Eigen::Index n = dyn.nv(), k = n - 6, c = Jc.rows();

  // -- contact-constrained dynamics
  Matrix Phi, Y;
  Matrix Xt(c, n);  // J̄_cᵀ
  if (c == 0) {
    Phi = Minv;
    Y = Matrix::Identity(n, n).bottomRows(k);
    p.qdd0.noalias() = -Minv * h;
    p.F.setZero(0, k);
    p.f0.setZero(0);
  } else {
    const Matrix B = Minv * Jc.transpose();  // (n, c)
    const Matrix JcB = Jc * B;
    Matrix Lc;
    // redundant contacts (several points on one frame: by construction) by the SVD
    if (dyn.contact_rows_redundant() || !spd_inverse(JcB, Lc)) psd_pinv(JcB, true, 1e-9, 0.0, Lc);
    Xt.noalias() = Lc * B.transpose();
    Phi = Minv;
    Phi.noalias() -= B * Xt;
    Phi = 0.5 * (Phi + Phi.transpose()).eval();
    Y.noalias() = -Xt.rightCols(k).transpose() * Jc;
    Y.rightCols(k).diagonal().array() += 1.0;
    p.qdd0.noalias() = -Phi * h;
    p.qdd0.noalias() -= Xt.transpose() * dJc;
    p.F = -Xt.rightCols(k);
    p.f0.noalias() = Xt * h;
    p.f0.noalias() -= Lc * dJc;
  }
  p.W = Phi.bottomRightCorner(k, k);
  p.Phi_a = Phi.rightCols(k);

  // -- the dynamically consistent inverse Ȳ and N_w
  const Decomposition dec =
      spec_.inverse == OsfInverse::kSvd ? svd(Y, spec_.rcond) : cod(Y, spec_.rcond);
  Matrix Ybar = dec.pinv;
  if (spec_.inverse != OsfInverse::kPinv && dec.right_null.cols() > 0) {
    const Matrix& v2 = dec.right_null;
    const Matrix Mv2 = M * v2;
    Eigen::LLT<Matrix> llt(v2.transpose() * Mv2);
    if (llt.info() != Eigen::Success) throw std::runtime_error("osf: v₂ᵀ M v₂ not SPD");
    const Matrix alpha = llt.solve(Mv2.transpose() * dec.pinv);  // eq. 19
    Ybar.noalias() -= v2 * alpha;
  }
  p.Nw = dec.left_null;

  // -- the levels: the products with every task row at once (fewer, larger GEMMs)
  const int L = static_cast<int>(spec_.level_dims.size());
  p.levels.resize(L);
  p.exact = spec_.exact;
  Matrix JPhi, JY, JMinv, N, a, aW, X, Jbar;
  JPhi.noalias() = J * p.Phi_a;
  JY.noalias() = J * Ybar;
  JMinv.noalias() = J * Minv;
  // each row's inverse inertia without contacts or levels above sets its level's rank scale
  const Vector inertia = JMinv.cwiseProduct(J).rowwise().sum();
  Eigen::Index row = 0;
  for (int i = 0; i < L; ++i) {
    const Eigen::Index m = spec_.level_dims[i];
    LevelParams& lv = p.levels[i];
    lv.Jhat = JPhi.middleRows(row, m);
    lv.bias = drift.segment(row, m);
    lv.bias.noalias() += J.middleRows(row, m) * p.qdd0;
    if (i == 0) {
      a = JY.middleRows(row, m);
    } else {
      a.noalias() = JY.middleRows(row, m) * N;
    }
    aW.noalias() = a * p.W;
    X.noalias() = aW * a.transpose();
    const double scale = m ? inertia.segment(row, m).maxCoeff() : 0.0;
    X = 0.5 * (X + X.transpose()).eval();
    psd_pinv(X, spec_.inverse == OsfInverse::kSvd, spec_.rcond, scale, lv.Lam);
    lv.Jstar = a;
    lv.B.noalias() = a.transpose() * lv.Lam;
    lv.E = spec_.force_level[i] ? Matrix(a.transpose()) : lv.B;
    if (i + 1 < L) {
      Jbar.noalias() = p.W * lv.B;
      if (i == 0) {
        N = -Jbar * a;
        N.diagonal().array() += 1.0;
      } else {
        const Matrix NJ = N * Jbar;
        N.noalias() -= NJ * a;
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
    Eigen::HouseholderQR<Matrix> qr(p.F * p.Nw);
    p.Qf = Matrix(qr.householderQ()).leftCols(np);
    const auto Rf = qr.matrixQR().topRows(np).triangularView<Eigen::Upper>();
    Matrix YcT = p.Nw.transpose();
    Rf.transpose().solveInPlace(YcT);
    p.Yc = YcT.transpose();
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
      const Eigen::Index m = spec_.level_dims[i];
      if (spec_.exact && col) {
        const Matrix JK = lv.Jhat * p.K.leftCols(col);
        p.K.leftCols(col).noalias() -= lv.B * JK;
        const Vector jg = lv.Jhat * p.gamma0;
        p.gamma0.noalias() -= lv.B * jg;
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
