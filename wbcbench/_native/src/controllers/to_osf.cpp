#include "controllers/to_osf.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>


namespace wbcbench {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

void ToOsfTick::configure(const ToOsfSettings& settings) {
  s_ = settings;
  configure_osf(settings, true);
  if (s_.row_weights.size() != nr_) throw std::invalid_argument("to_osf: one weight per task row");
  if (s_.Sf.cols() != nc_) throw std::invalid_argument("to_osf: Sf of wrong size");
  // F_opt = N w when the first contact's block of G is invertible (the Python reference's test,
  // on the initial configuration's shape: 6-D contacts keep it invertible), for the contact set
  // configured: a single 6-D contact has no internal wrench (nf = 0), two have six
  basis_ = s_.internal_basis && nc_ >= 6;
  nf_ = basis_ ? nc_ - 6 : nc_;
  nx_ = nr_ + nf_;
  h_task_ = s_.row_weights;
  scale_ = nr_ ? 1.0 / h_task_.maxCoeff() : 1.0;
  // F_opt is solved for in units of σ so that both Hessian blocks are O(1)
  w_f_ = (nc_ && s_.wrench_weight > 0) ? scale_ * s_.wrench_weight : scale_;
  const double sigma = 1.0 / std::sqrt(w_f_);
  D_.setOnes(nx_);
  D_.tail(nf_).setConstant(sigma);
  const bool box = (s_.acc_bound.array().abs() < kInf).any();
  qp_.resize(nx_, nc_ && !basis_ ? 6 : 0, k() + static_cast<int>(s_.Cw.rows()), box);
  if (box) {
    qp_.lb.head(nr_) = -s_.acc_bound;
    qp_.ub.head(nr_) = s_.acc_bound;
  }
  Af_.setZero(nc_, nx_);
  if (!basis_) Af_.rightCols(nc_).setIdentity();
  N_.setZero(nc_, nf_);
  if (basis_) N_.bottomRows(nf_).setIdentity();
  rho_.setZero(nr_);
  f_opt_.setZero(nc_);
}

bool ToOsfTick::build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                      double t) {
  const auto t0 = Clock::now();
  evaluate_osf(q, v, t);
  const OsfParams& p = params_;
  if (basis_ && !internal_basis()) {
    throw std::runtime_error(
        "to_osf: the grasp map's first contact block is singular; use internal: constraint");
  }
  const int kk = k();
  const Vector& ref = level_ref();
  // f = A_f x + f_c  (eq. 13)
  Af_.leftCols(nr_).noalias() = p.F * p.K;
  if (basis_ && nf_ > 0) Af_.rightCols(nf_) = N_;
  fc_ = p.f0;
  fc_.noalias() += p.F * p.gamma0;
  qp_.H.setZero();
  qp_.g.setZero();
  qp_.H.topLeftCorner(nr_, nr_).diagonal() = scale_ * h_task_;
  qp_.g.head(nr_) = -scale_ * h_task_.cwiseProduct(ref);
  if (nc_ && s_.wrench_weight > 0) {
    const double hw = scale_ * s_.wrench_weight;
    if (s_.wrench_total) {
      SA_.noalias() = s_.Sf * Af_;
      qp_.H.noalias() += hw * (SA_.transpose() * SA_);
      sf_fc_.noalias() = s_.Sf * fc_;
      qp_.g.noalias() += hw * (SA_.transpose() * sf_fc_);
    } else if (basis_) {
      if (nf_ > 0) {  // (a single contact has no internal wrench)
        SA_.noalias() = s_.Sf * N_;
        qp_.H.bottomRightCorner(nf_, nf_).noalias() += hw * (SA_.transpose() * SA_);
      }
    } else {
      qp_.H.bottomRightCorner(nc_, nc_).noalias() += hw * (s_.Sf.transpose() * s_.Sf);
    }
  }
  if (basis_ && nf_ > 0) {  // ‖F_opt‖² = wᵀ NᵀN w
    qp_.H.bottomRightCorner(nf_, nf_).noalias() +=
        (s_.regularization * w_f_) * (N_.transpose() * N_);
  } else if (!basis_) {
    qp_.H.bottomRightCorner(nc_, nc_).diagonal().array() += s_.regularization * w_f_;
    if (nc_) qp_.A.rightCols(nc_) = p.G;  // G F_opt = 0 (eq. 14)
  }
  qp_.C.topLeftCorner(kk, nr_) = p.K;
  if (basis_) {
    if (nf_ > 0) qp_.C.topRightCorner(kk, nf_).noalias() = p.Yw * N_;
  } else {
    qp_.C.topRightCorner(kk, nc_) = p.Yw;
  }
  qp_.l.head(kk) = -s_.tau_max - p.gamma0;
  qp_.u.head(kk) = s_.tau_max - p.gamma0;
  if (nc_) {
    qp_.C.bottomRows(nw_).noalias() = s_.Cw * Af_;
    cw_fc_.noalias() = s_.Cw * fc_;
    qp_.l.tail(nw_) = os_.lw - cw_fc_;
    qp_.u.tail(nw_) = os_.uw - cw_fc_;
  }
  // x = D x̃
  qp_.H = D_.asDiagonal() * qp_.H * D_.asDiagonal();
  qp_.g.array() *= D_.array();
  qp_.A = qp_.A * D_.asDiagonal();
  qp_.C = qp_.C * D_.asDiagonal();
  const bool ok = qp_.finite();
  times_.build = seconds_since(t0) - times_.dynamics - times_.params;
  return ok;
}

void ToOsfTick::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                  const Eigen::Ref<const Vector>& uw) {
  store_wrench_bounds("to_osf", os_, lw, uw);
}

bool ToOsfTick::internal_basis() {
  const Matrix& G = params_.G;
  lu_.compute(G.leftCols(6));  // (the member keeps its storage from tick to tick)
  if (!(lu_.rcond() > 1e-12)) return false;
  if (nf_ > 0) N_.topRows(6).noalias() = -lu_.solve(G.rightCols(nf_));
  return true;
}

void ToOsfTick::finish(const Eigen::Ref<const Vector>& x) {
  const auto t0 = Clock::now();
  if (x.size() != nx_) throw std::invalid_argument("to_osf: solution of wrong size");
  rho_ = x.head(nr_);  // x = D x̃: D is 1 on the references, σ on F_opt
  if (basis_) {
    f_opt_.setZero(nc_);
    if (nf_ > 0) f_opt_.noalias() = N_ * x.tail(nf_).cwiseProduct(D_.tail(nf_));
  } else {
    f_opt_ = x.tail(nc_).cwiseProduct(D_.tail(nc_));
  }
  prev_.setZero(k());
  for (int i = 0; i < levels(); ++i) {
    params_.level_step(i, prev_, rho_.segment(offsets_[i], os_.level_dims[i]), work_);
    partial_.row(i) = work_.transpose();
    prev_ = work_;
  }
  dist_.setZero(k());
  if (nc_) dist_.noalias() = params_.Yw * f_opt_;
  realise(dist_);
  if (nc_ && dyn_.contact_rows_redundant()) {
    // the QP's distribution: F_opt's part no torque produces (forces along a line contact,
    // which change no wrench at the frame) is the one that holds each point in its cone
    wrench_ += f_opt_;
    qf_f_.noalias() = params_.Qf.transpose() * f_opt_;
    wrench_.noalias() -= params_.Qf * qf_f_;
  }
  times_.build += seconds_since(t0);
}

}  // namespace wbcbench
