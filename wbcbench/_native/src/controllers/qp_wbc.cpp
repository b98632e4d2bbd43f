#include "controllers/qp_wbc.hpp"

#include <stdexcept>

namespace wbcbench {

QpWbcTick::QpWbcTick(const std::string& model, const std::vector<std::string>& task_frames,
                     const std::vector<std::string>& contact_frames)
    : Tick(model, task_frames, contact_frames) {
  dyn_.set_inverse(false);  // the QP reads M, never M⁻¹
}

void QpWbcTick::contacts_switched(int set) {
  const auto i = static_cast<size_t>(set);
  w_ = i < work_.size() ? work_[i].get() : nullptr;
}

QpWbcTick::Workspace& QpWbcTick::work() {
  if (w_ == nullptr)
    throw std::logic_error("qp_wbc: the tick's contact set is not configured (configure first)");
  return *w_;
}

QpBuffers& QpWbcTick::qp() { return work().qp; }

const Vector& QpWbcTick::wrench() const {
  static const Vector none;
  return w_ == nullptr ? none : w_->wrench;
}

void QpWbcTick::configure(const QpWbcSettings& settings) {
  n_ = nv();
  k_ = k();
  const int nc = static_cast<int>(dyn_.contact_jacobian().rows());
  const int nk = static_cast<int>(dyn_.constraint_jacobian().rows());
  const int nw = static_cast<int>(settings.Cw.rows());
  if (settings.row_weights.size() != tasks_.rows())
    throw std::invalid_argument("qp_wbc: one weight per task row");
  if (settings.tau_max.size() != k_) throw std::invalid_argument("qp_wbc: tau_max of wrong size");
  if (settings.Cw.cols() != nc || settings.lw.size() != nw || settings.uw.size() != nw)
    throw std::invalid_argument("qp_wbc: wrench constraints of wrong size");
  const auto set = static_cast<size_t>(set_);
  if (work_.size() <= set) work_.resize(set + 1);
  if (!work_[set]) work_[set] = std::make_unique<Workspace>();
  Workspace& w = *(w_ = work_[set].get());
  w.s = settings;
  w.nc = nc;
  w.nk = nk;
  const QpWbcSettings& s = w.s;
  JW_.setZero(tasks_.rows(), n_);
  r_.setZero(tasks_.rows());
  tau_.setZero(k_);
  qdd_.setZero(n_);
  w.wrench.setZero(nc);
  if (!s.eliminated) {  // x = (q̈, Γ, f)
    w.nx = n_ + k_ + nc;
    w.qp.resize(w.nx, n_ + nk, nw, true);
    w.qp.H.block(n_, n_, k_, k_).diagonal().setConstant(s.torque_weight);
    w.qp.H.block(n_ + k_, n_ + k_, nc, nc).diagonal().setConstant(s.wrench_weight);
    w.qp.A.block(6, n_, k_, k_).diagonal().setConstant(-1.0);
    w.qp.C.rightCols(nc) = s.Cw;
    w.qp.l = s.lw;
    w.qp.u = s.uw;
    w.qp.lb.segment(n_, k_) = -s.tau_max;
    w.qp.ub.segment(n_, k_) = s.tau_max;
  } else {  // x = (q̈, f), Γ = G x + γ from the actuated rows of the dynamics
    w.nx = n_ + nc;
    w.qp.resize(w.nx, 6 + nk, nw + k_, false);
    w.qp.C.topRightCorner(nw, nc) = s.Cw;
    w.qp.l.head(nw) = s.lw;
    w.qp.u.head(nw) = s.uw;
    w.G.setZero(k_, w.nx);
    w.gamma.setZero(k_);
  }
}

bool QpWbcTick::build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                      double t) {
  const auto t0 = Clock::now();
  Workspace& w = work();
  const QpWbcSettings& s = w.s;
  const int nc = w.nc, nk = w.nk;
  QpBuffers& qp = w.qp;
  evaluate(q, v, t);
  const Matrix& M = dyn_.M();
  const Vector& h = dyn_.h();
  const Matrix& Jc = dyn_.contact_jacobian();
  // J_c q̈ + J̇_c q̇ = 0 on the rows independent by construction
  const Matrix& Jk = dyn_.constraint_jacobian();
  const Vector& dJk = dyn_.constraint_drift();
  const Matrix& J = tasks_.J();

  // Σ w Jᵀ J + w_q̈ I and −Σ w Jᵀ (ẍ* − J̇ q̇)
  JW_.noalias() = s.row_weights.asDiagonal() * J;
  r_ = tasks_.acc_ref() - tasks_.drift();
  auto Hq = qp.H.topLeftCorner(n_, n_);
  Hq.noalias() = J.transpose() * JW_;
  Hq.diagonal().array() += s.acceleration_weight;
  qp.g.head(n_).noalias() = -JW_.transpose() * r_;

  if (!s.eliminated) {
    qp.A.topLeftCorner(n_, n_) = M;
    qp.A.block(0, n_ + k_, n_, nc) = -Jc.transpose();
    qp.b.head(n_) = -h;
    qp.A.block(n_, 0, nk, n_) = Jk;
    qp.b.tail(nk) = -dJk;
  } else {
    RowMatrix& G = w.G;
    G.leftCols(n_) = M.bottomRows(k_);
    G.rightCols(nc) = -Jc.rightCols(k_).transpose();
    w.gamma = h.tail(k_);
    qp.H.bottomRightCorner(nc, nc).setZero();
    qp.H.bottomRightCorner(nc, nc).diagonal().setConstant(s.wrench_weight);
    qp.H.topRightCorner(n_, nc).setZero();
    qp.H.bottomLeftCorner(nc, n_).setZero();
    qp.H.noalias() += s.torque_weight * (G.transpose() * G);
    qp.g.tail(nc).setZero();
    qp.g.noalias() += s.torque_weight * (G.transpose() * w.gamma);
    qp.A.topLeftCorner(6, n_) = M.topRows(6);
    qp.A.topRightCorner(6, nc) = -Jc.leftCols(6).transpose();
    qp.b.head(6) = -h.head(6);
    qp.A.bottomLeftCorner(nk, n_) = Jk;
    qp.b.tail(nk) = -dJk;
    qp.C.bottomRows(k_) = G;
    qp.l.tail(k_) = -s.tau_max - w.gamma;
    qp.u.tail(k_) = s.tau_max - w.gamma;
  }
  const bool ok = qp.finite();
  times_.build = seconds_since(t0) - times_.dynamics;
  return ok;
}

void QpWbcTick::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                  const Eigen::Ref<const Vector>& uw) {
  Workspace& w = work();
  store_wrench_bounds("qp_wbc", w.s, lw, uw);
  const auto nw = lw.size();
  w.qp.l.head(nw) = lw;
  w.qp.u.head(nw) = uw;
}

void QpWbcTick::finish(const Eigen::Ref<const Vector>& x) {
  const auto t0 = Clock::now();
  Workspace& w = work();
  if (x.size() != w.nx) throw std::invalid_argument("qp_wbc: solution of wrong size");
  qdd_ = x.head(n_);
  w.wrench = x.tail(w.nc);
  if (!w.s.eliminated)
    tau_ = x.segment(n_, k_);
  else
    tau_.noalias() = w.G * x + w.gamma;
  times_.build += seconds_since(t0);
}

}  // namespace wbcbench
