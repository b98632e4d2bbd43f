#include "controllers/to_osf.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>


namespace wbcbench {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

void ToOsfTick::configure(const ToOsfSettings& settings) {
  configure_osf(settings, true);
  Set& w = set();
  w.s = settings;
  const int nr = w.nr, nc = w.nc, kk = k();
  if (w.s.row_weights.size() != nr) throw std::invalid_argument("to_osf: one weight per task row");
  if (w.s.Sf.cols() != nc) throw std::invalid_argument("to_osf: Sf of wrong size");
  // F_opt = N w when the first contact's block of G is invertible (the Python reference's test,
  // on the initial configuration's shape: 6-D contacts keep it invertible), for the contact set
  // configured: a single 6-D contact has no internal wrench (nf = 0), two have six
  w.basis = w.s.internal_basis && nc >= 6;
  w.nf = w.basis ? nc - 6 : nc;
  w.nx = nr + w.nf;
  w.h_task = w.s.row_weights;
  w.scale = nr ? 1.0 / w.h_task.maxCoeff() : 1.0;
  // F_opt is solved for in units of σ so that both Hessian blocks are O(1)
  w.w_f = (nc && w.s.wrench_weight > 0) ? w.scale * w.s.wrench_weight : w.scale;
  const double sigma = 1.0 / std::sqrt(w.w_f);
  w.D.setOnes(w.nx);
  w.D.tail(w.nf).setConstant(sigma);
  const bool box = (w.os.acc_bound.array().abs() < kInf).any();
  w.qp.resize(w.nx, nc && !w.basis ? 6 : 0, kk + static_cast<int>(w.s.Cw.rows()), box);
  if (box) {
    w.qp.lb.head(nr) = -w.os.acc_bound;
    w.qp.ub.head(nr) = w.os.acc_bound;
  }
  w.Af.setZero(nc, w.nx);
  if (!w.basis) w.Af.rightCols(nc).setIdentity();
  w.N.setZero(nc, w.nf);
  if (w.basis) w.N.bottomRows(w.nf).setIdentity();
  w.rho.setZero(nr);
  w.f_opt.setZero(nc);
  w.fc.setZero(nc);
  w.x_f.setZero(w.nf);
  // what build() forms each tick, at its sizes
  const auto nsf = w.s.Sf.rows();
  w.SA.setZero(nsf, w.s.wrench_total ? w.nx : w.nf);
  w.sf_fc.setZero(nsf);
  w.cw_fc.setZero(w.nw);
  prev_.setZero(kk);
  step_.setZero(kk);
  dist_.setZero(kk);
}

bool ToOsfTick::build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                      double t) {
  const auto t0 = Clock::now();
  evaluate_osf(q, v, t);
  Set& w = set();
  const OsfParams& p = w.params;
  const ToOsfSettings& s = w.s;
  const int nr = w.nr, nc = w.nc, nf = w.nf, nw = w.nw;
  QpBuffers& qp = w.qp;
  if (w.basis && !internal_basis(w)) {
    throw std::runtime_error(
        "to_osf: the grasp map's first contact block is singular; use internal: constraint");
  }
  const int kk = k();
  const Vector& ref = level_ref();
  // f = A_f x + f_c  (eq. 13)
  w.Af.leftCols(nr).noalias() = p.F * p.K;
  if (w.basis && nf > 0) w.Af.rightCols(nf) = w.N;
  w.fc = p.f0;
  w.fc.noalias() += p.F * p.gamma0;
  qp.H.setZero();
  qp.g.setZero();
  qp.H.topLeftCorner(nr, nr).diagonal() = w.scale * w.h_task;
  qp.g.head(nr) = -w.scale * w.h_task.cwiseProduct(ref);
  if (nc && s.wrench_weight > 0) {
    const double hw = w.scale * s.wrench_weight;
    if (s.wrench_total) {
      w.SA.noalias() = s.Sf * w.Af;
      qp.H.noalias() += hw * (w.SA.transpose() * w.SA);
      w.sf_fc.noalias() = s.Sf * w.fc;
      qp.g.noalias() += hw * (w.SA.transpose() * w.sf_fc);
    } else if (w.basis) {
      if (nf > 0) {  // (a single contact has no internal wrench)
        w.SA.noalias() = s.Sf * w.N;
        qp.H.bottomRightCorner(nf, nf).noalias() += hw * (w.SA.transpose() * w.SA);
      }
    } else {
      qp.H.bottomRightCorner(nc, nc).noalias() += hw * (s.Sf.transpose() * s.Sf);
    }
  }
  if (w.basis && nf > 0) {  // ‖F_opt‖² = wᵀ NᵀN w
    qp.H.bottomRightCorner(nf, nf).noalias() +=
        (s.regularization * w.w_f) * (w.N.transpose() * w.N);
  } else if (!w.basis) {
    qp.H.bottomRightCorner(nc, nc).diagonal().array() += s.regularization * w.w_f;
    if (nc) qp.A.rightCols(nc) = p.G;  // G F_opt = 0 (eq. 14)
  }
  qp.C.topLeftCorner(kk, nr) = p.K;
  if (w.basis) {
    if (nf > 0) qp.C.topRightCorner(kk, nf).noalias() = p.Yw * w.N;
  } else {
    qp.C.topRightCorner(kk, nc) = p.Yw;
  }
  qp.l.head(kk) = -s.tau_max - p.gamma0;
  qp.u.head(kk) = s.tau_max - p.gamma0;
  if (nc) {
    qp.C.bottomRows(nw).noalias() = s.Cw * w.Af;
    w.cw_fc.noalias() = s.Cw * w.fc;
    qp.l.tail(nw) = w.os.lw - w.cw_fc;
    qp.u.tail(nw) = w.os.uw - w.cw_fc;
  }
  // x = D x̃
  qp.H = w.D.asDiagonal() * qp.H * w.D.asDiagonal();
  qp.g.array() *= w.D.array();
  qp.A = qp.A * w.D.asDiagonal();
  qp.C = qp.C * w.D.asDiagonal();
  const bool ok = qp.finite();
  times_.build = seconds_since(t0) - times_.dynamics - times_.params;
  return ok;
}

void ToOsfTick::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                  const Eigen::Ref<const Vector>& uw) {
  store_wrench_bounds("to_osf", w().os, lw, uw);
}

bool ToOsfTick::internal_basis(Set& w) {
  const Matrix& G = w.params.G;
  // the reference's test, cond₁(B) < 1e12, on the 6 × 6 block B (its inverse formed on the
  // stack: allocation-free)
  const Eigen::Matrix<double, 6, 6> B = G.leftCols(6);
  lu_.compute(B);
  const Eigen::Matrix<double, 6, 6> Binv = lu_.inverse();
  const double norm = B.cwiseAbs().colwise().sum().maxCoeff();
  const double inv_norm = Binv.cwiseAbs().colwise().sum().maxCoeff();
  if (!(1.0 / (norm * inv_norm) > 1e-12)) return false;
  if (w.nf > 0) {
    w.N.topRows(6) = lu_.solve(G.rightCols(w.nf));
    w.N.topRows(6) *= -1.0;
  }
  return true;
}

void ToOsfTick::finish(const Eigen::Ref<const Vector>& x) {
  const auto t0 = Clock::now();
  Set& w = set();
  const OsfParams& p = w.params;
  const int nr = w.nr, nc = w.nc, nf = w.nf;
  if (x.size() != w.nx) throw std::invalid_argument("to_osf: solution of wrong size");
  w.rho = x.head(nr);  // x = D x̃: D is 1 on the references, σ on F_opt
  if (w.basis) {
    w.f_opt.setZero(nc);
    if (nf > 0) {
      w.x_f = x.tail(nf).cwiseProduct(w.D.tail(nf));
      w.f_opt.noalias() = w.N * w.x_f;
    }
  } else {
    w.f_opt = x.tail(nc).cwiseProduct(w.D.tail(nc));
  }
  prev_.setZero();
  for (int i = 0; i < levels(); ++i) {
    const int m = w.os.level_dims[i];
    p.level_step(i, prev_, w.rho.segment(w.offsets[i], m), step_, w.level_work.head(m));
    w.partial.row(i) = step_.transpose();
    prev_.swap(step_);
  }
  dist_.setZero();
  if (nc) dist_.noalias() = p.Yw * w.f_opt;
  realise(dist_);
  if (nc && dyn_.contact_rows_redundant()) {
    // the QP's distribution: F_opt's part no torque produces (forces along a line contact,
    // which change no wrench at the frame) is the one that holds each point in its cone
    w.wrench += w.f_opt;
    w.qf_f.noalias() = p.Qf.transpose() * w.f_opt;
    w.wrench.noalias() -= p.Qf * w.qf_f;
  }
  times_.build += seconds_since(t0);
}

}  // namespace wbcbench
