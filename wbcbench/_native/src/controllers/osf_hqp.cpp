#include "controllers/osf_hqp.hpp"

#include <limits>
#include <stdexcept>
#include <string>

namespace wbcbench {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

void OsfHqpTick::configure(const OsfHqpSettings& settings) {
  s_ = settings;
  configure_osf(settings, false);
  if (s_.WtW.rows() != nc_ || s_.WtW.cols() != nc_)
    throw std::invalid_argument("osf_hqp: WtW of wrong size");
  // the wrench-distribution space of independent plane contacts: dim null(W) = c − 6
  np_ = s_.distribution >= 0 ? s_.distribution : (nc_ > 6 ? nc_ - 6 : 0);
  const int L = levels(), kk = k();
  qps_.clear();
  qps_.reserve(L + 1);  // the buffers' addresses never change after this
  for (int i = 0; i < L; ++i) {
    const int m = os_.level_dims[i];
    const auto bound = os_.acc_bound.segment(offsets_[i], m);
    const bool box = (bound.array().abs() < kInf).any();
    QpBuffers& qp = qps_.emplace_back();
    qp.resize(m + np_, 0, kk + nw_, box);
    qp.H.diagonal().head(m).setOnes();
    qp.H.diagonal().tail(np_).setConstant(s_.regularization);
  }
  if (np_) {
    QpBuffers& qp = qps_.emplace_back();
    qp.resize(np_, 0, kk + nw_, false);
  }
  slack_.setZero(L);
}

void OsfHqpTick::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                   const Eigen::Ref<const Vector>& uw) {
  store_wrench_bounds("osf_hqp", os_, lw, uw);
}

bool OsfHqpTick::build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                       double t) {
  const auto t0 = Clock::now();
  evaluate_osf(q, v, t);
  message_.clear();
  const OsfParams& p = params_;
  if (p.Yc.cols() != np_) {
    message_ = "the wrench-distribution space has dimension " + std::to_string(p.Yc.cols()) +
               ", not " + std::to_string(np_) + " (a contact Jacobian lost rank?)";
    times_.build = seconds_since(t0) - times_.dynamics - times_.params;
    return false;
  }
  cw_f0_.noalias() = s_.Cw * p.f0;
  CwF_.noalias() = s_.Cw * p.F;
  CwQ_.noalias() = s_.Cw * p.Qf;
  tau_.setZero(k());
  build_level(0);
  const bool ok = levels() == 0 || qps_[0].finite();
  times_.build = seconds_since(t0) - times_.dynamics - times_.params;
  return ok;
}

void OsfHqpTick::build_level(int i) {
  if (i >= levels()) return;
  const OsfParams& p = params_;
  const int m = os_.level_dims[i], kk = k();
  const auto ref = level_ref().segment(offsets_[i], m);
  p.level_step(i, tau_, ref, base_);  // Γ_{≤l} with w_l = 0
  const Matrix& E = p.levels[i].E;
  QpBuffers& qp = qps_[i];
  qp.C.topLeftCorner(kk, m) = E;
  qp.C.topRightCorner(kk, np_) = p.Yc;
  qp.C.bottomLeftCorner(nw_, m).noalias() = CwF_ * E;
  qp.C.bottomRightCorner(nw_, np_) = CwQ_;
  const double tol = s_.carry_tolerance * i;
  qp.l.head(kk) = -s_.tau_max - base_;
  qp.u.head(kk) = s_.tau_max - base_;
  if (nw_) {
    Vector cwb = cw_f0_;
    cwb.noalias() += CwF_ * base_;
    qp.l.tail(nw_) = os_.lw - cwb;
    qp.u.tail(nw_) = os_.uw - cwb;
  }
  qp.l.array() -= tol;
  qp.u.array() += tol;
  if (qp.has_box) {  // |ẍ* + w| ≤ ẍ_max on the slacks, F_r free
    const auto bound = os_.acc_bound.segment(offsets_[i], m);
    qp.lb.head(m) = -bound - ref;
    qp.ub.head(m) = bound - ref;
  }
}

void OsfHqpTick::build_wrench() {
  const OsfParams& p = params_;
  const int kk = k(), L = levels();
  QpBuffers& qp = qps_.back();
  ftask_ = p.f0;
  ftask_.noalias() += p.F * tau_;
  QW_.noalias() = p.Qf.transpose() * s_.WtW;
  qp.H.noalias() = QW_ * p.Qf;
  qp.H.diagonal().array() += s_.regularization;
  qp.g.noalias() = QW_ * ftask_;
  qp.C.topRows(kk) = p.Yc;
  qp.C.bottomRows(nw_) = CwQ_;
  const Vector cwt = s_.Cw * ftask_;
  const double tol = s_.carry_tolerance * L;
  qp.l.head(kk) = -s_.tau_max - tau_;
  qp.u.head(kk) = s_.tau_max - tau_;
  qp.l.tail(nw_) = os_.lw - cwt;
  qp.u.tail(nw_) = os_.uw - cwt;
  qp.l.array() -= tol;
  qp.u.array() += tol;
}

bool OsfHqpTick::level(int i, const Eigen::Ref<const Vector>& x) {
  const auto t0 = Clock::now();
  const int m = os_.level_dims.at(i);
  if (x.size() != m + np_) throw std::invalid_argument("osf_hqp: level solution of wrong size");
  tau_ = base_;
  tau_.noalias() += params_.levels[i].E * x.head(m);
  partial_.row(i) = tau_.transpose();
  slack_(i) = x.head(m).norm();
  bool ok = true;
  if (i + 1 < levels()) {
    build_level(i + 1);
    ok = qps_[i + 1].finite();
  } else if (np_) {
    build_wrench();
    ok = qps_.back().finite();
  }
  times_.build += seconds_since(t0);
  return ok;
}

void OsfHqpTick::finish(const Eigen::Ref<const Vector>& x) {
  const auto t0 = Clock::now();
  if (x.size() != np_) throw std::invalid_argument("osf_hqp: wrench solution of wrong size");
  Vector dist = Vector::Zero(k());
  if (np_) dist.noalias() = params_.Yc * x;
  realise(dist);
  times_.build += seconds_since(t0);
}

}  // namespace wbcbench
