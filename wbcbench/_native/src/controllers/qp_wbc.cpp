#include "controllers/qp_wbc.hpp"

#include <stdexcept>

namespace wbcbench {

QpWbcTick::QpWbcTick(const std::string& model, const std::vector<std::string>& task_frames,
                     const std::vector<std::string>& contact_frames)
    : Tick(model, task_frames, contact_frames) {
  dyn_.set_inverse(false);  // the QP reads M, never M⁻¹
}

void QpWbcTick::configure(const QpWbcSettings& settings) {
  s_ = settings;
  n_ = nv();
  k_ = k();
  nc_ = static_cast<int>(dyn_.contact_jacobian().rows());
  nk_ = static_cast<int>(dyn_.constraint_jacobian().rows());
  const int nw = static_cast<int>(s_.Cw.rows());
  if (s_.row_weights.size() != tasks_.rows())
    throw std::invalid_argument("qp_wbc: one weight per task row");
  if (s_.tau_max.size() != k_) throw std::invalid_argument("qp_wbc: tau_max of wrong size");
  if (s_.Cw.cols() != nc_ || s_.lw.size() != nw || s_.uw.size() != nw)
    throw std::invalid_argument("qp_wbc: wrench constraints of wrong size");
  JW_.setZero(tasks_.rows(), n_);
  r_.setZero(tasks_.rows());
  tau_.setZero(k_);
  qdd_.setZero(n_);
  wrench_.setZero(nc_);
  if (!s_.eliminated) {  // x = (q̈, Γ, f)
    nx_ = n_ + k_ + nc_;
    qp_.resize(nx_, n_ + nk_, nw, true);
    qp_.H.block(n_, n_, k_, k_).diagonal().setConstant(s_.torque_weight);
    qp_.H.block(n_ + k_, n_ + k_, nc_, nc_).diagonal().setConstant(s_.wrench_weight);
    qp_.A.block(6, n_, k_, k_).diagonal().setConstant(-1.0);
    qp_.C.rightCols(nc_) = s_.Cw;
    qp_.l = s_.lw;
    qp_.u = s_.uw;
    qp_.lb.segment(n_, k_) = -s_.tau_max;
    qp_.ub.segment(n_, k_) = s_.tau_max;
  } else {  // x = (q̈, f), Γ = G x + γ from the actuated rows of the dynamics
    nx_ = n_ + nc_;
    qp_.resize(nx_, 6 + nk_, nw + k_, false);
    qp_.C.topRightCorner(nw, nc_) = s_.Cw;
    qp_.l.head(nw) = s_.lw;
    qp_.u.head(nw) = s_.uw;
    G_.setZero(k_, nx_);
    gamma_.setZero(k_);
  }
}

bool QpWbcTick::build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                      double t) {
  const auto t0 = Clock::now();
  evaluate(q, v, t);
  const Matrix& M = dyn_.M();
  const Vector& h = dyn_.h();
  const Matrix& Jc = dyn_.contact_jacobian();
  // J_c q̈ + J̇_c q̇ = 0 on the rows independent by construction
  const Matrix& Jk = dyn_.constraint_jacobian();
  const Vector& dJk = dyn_.constraint_drift();
  const Matrix& J = tasks_.J();

  // Σ w Jᵀ J + w_q̈ I and −Σ w Jᵀ (ẍ* − J̇ q̇)
  JW_.noalias() = s_.row_weights.asDiagonal() * J;
  r_ = tasks_.acc_ref() - tasks_.drift();
  auto Hq = qp_.H.topLeftCorner(n_, n_);
  Hq.noalias() = J.transpose() * JW_;
  Hq.diagonal().array() += s_.acceleration_weight;
  qp_.g.head(n_).noalias() = -JW_.transpose() * r_;

  if (!s_.eliminated) {
    qp_.A.topLeftCorner(n_, n_) = M;
    qp_.A.block(0, n_ + k_, n_, nc_) = -Jc.transpose();
    qp_.b.head(n_) = -h;
    qp_.A.block(n_, 0, nk_, n_) = Jk;
    qp_.b.tail(nk_) = -dJk;
  } else {
    G_.leftCols(n_) = M.bottomRows(k_);
    G_.rightCols(nc_) = -Jc.rightCols(k_).transpose();
    gamma_ = h.tail(k_);
    qp_.H.bottomRightCorner(nc_, nc_).setZero();
    qp_.H.bottomRightCorner(nc_, nc_).diagonal().setConstant(s_.wrench_weight);
    qp_.H.topRightCorner(n_, nc_).setZero();
    qp_.H.bottomLeftCorner(nc_, n_).setZero();
    qp_.H.noalias() += s_.torque_weight * (G_.transpose() * G_);
    qp_.g.tail(nc_).setZero();
    qp_.g.noalias() += s_.torque_weight * (G_.transpose() * gamma_);
    qp_.A.topLeftCorner(6, n_) = M.topRows(6);
    qp_.A.topRightCorner(6, nc_) = -Jc.leftCols(6).transpose();
    qp_.b.head(6) = -h.head(6);
    qp_.A.bottomLeftCorner(nk_, n_) = Jk;
    qp_.b.tail(nk_) = -dJk;
    qp_.C.bottomRows(k_) = G_;
    qp_.l.tail(k_) = -s_.tau_max - gamma_;
    qp_.u.tail(k_) = s_.tau_max - gamma_;
  }
  const bool ok = qp_.finite();
  times_.build = seconds_since(t0) - times_.dynamics;
  return ok;
}

void QpWbcTick::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                  const Eigen::Ref<const Vector>& uw) {
  store_wrench_bounds("qp_wbc", s_, lw, uw);
  const auto nw = lw.size();
  qp_.l.head(nw) = lw;
  qp_.u.head(nw) = uw;
}

void QpWbcTick::finish(const Eigen::Ref<const Vector>& x) {
  const auto t0 = Clock::now();
  if (x.size() != nx_) throw std::invalid_argument("qp_wbc: solution of wrong size");
  qdd_ = x.head(n_);
  wrench_ = x.tail(nc_);
  if (!s_.eliminated)
    tau_ = x.segment(n_, k_);
  else
    tau_.noalias() = G_ * x + gamma_;
  times_.build += seconds_since(t0);
}

}  // namespace wbcbench
