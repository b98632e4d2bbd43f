#include "controllers/osf_hqp.hpp"

#include <limits>
#include <stdexcept>
#include <string>

namespace wbcbench {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

void OsfHqpTick::configure(const OsfHqpSettings& settings) {
  configure_osf(settings, false);
  Set& w = set();
  w.s = settings;
  const int nc = w.nc, nw = w.nw;
  if (w.s.WtW.rows() != nc || w.s.WtW.cols() != nc)
    throw std::invalid_argument("osf_hqp: WtW of wrong size");
  // the wrench-distribution space of independent plane contacts: dim null(W) = c − 6
  const int np = w.np = w.s.distribution >= 0 ? w.s.distribution : (nc > 6 ? nc - 6 : 0);
  const int L = levels(), kk = k();
  w.qps.clear();
  w.qps.reserve(L + 1);  // the buffers' addresses never change after this
  for (int i = 0; i < L; ++i) {
    const int m = w.os.level_dims[i];
    const auto bound = w.os.acc_bound.segment(w.offsets[i], m);
    const bool box = (bound.array().abs() < kInf).any();
    QpBuffers& qp = w.qps.emplace_back();
    qp.resize(m + np, 0, kk + nw, box);
    qp.H.diagonal().head(m).setOnes();
    qp.H.diagonal().tail(np).setConstant(w.s.regularization);
  }
  if (np) {
    QpBuffers& qp = w.qps.emplace_back();
    qp.resize(np, 0, kk + nw, false);
  }
  w.slack.setZero(L);
  // what each tick forms, at its sizes
  w.cw_f0.setZero(nw);
  w.cw_base.setZero(nw);
  w.ftask.setZero(nc);
  w.CwF.setZero(nw, kk);
  w.CwQ.setZero(nw, np);
  w.QW.setZero(np, nc);
  base_.setZero(kk);
  dist_.setZero(kk);
}

void OsfHqpTick::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                   const Eigen::Ref<const Vector>& uw) {
  store_wrench_bounds("osf_hqp", w().os, lw, uw);
}

bool OsfHqpTick::build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                       double t) {
  const auto t0 = Clock::now();
  evaluate_osf(q, v, t);
  message_.clear();
  Set& w = set();
  const OsfParams& p = w.params;
  if (p.Yc.cols() != w.np) {
    message_ = "the wrench-distribution space has dimension " + std::to_string(p.Yc.cols()) +
               ", not " + std::to_string(w.np) + " (a contact Jacobian lost rank?)";
    times_.build = seconds_since(t0) - times_.dynamics - times_.params;
    return false;
  }
  w.cw_f0.noalias() = w.s.Cw * p.f0;
  w.CwF.noalias() = w.s.Cw * p.F;
  w.CwQ.noalias() = w.s.Cw * p.Qf;
  tau_.setZero();
  build_level(w, 0);
  const bool ok = levels() == 0 || w.qps[0].finite();
  times_.build = seconds_since(t0) - times_.dynamics - times_.params;
  return ok;
}

void OsfHqpTick::build_level(Set& w, int i) {
  if (i >= levels()) return;
  const OsfParams& p = w.params;
  const int m = w.os.level_dims[i], kk = k(), np = w.np, nw = w.nw;
  const auto ref = level_ref().segment(w.offsets[i], m);
  p.level_step(i, tau_, ref, base_, w.level_work.head(m));  // Γ_{≤l} with w_l = 0
  const Matrix& E = p.levels[i].E;
  QpBuffers& qp = w.qps[i];
  qp.C.topLeftCorner(kk, m) = E;
  qp.C.topRightCorner(kk, np) = p.Yc;
  qp.C.bottomLeftCorner(nw, m).noalias() = w.CwF * E;
  qp.C.bottomRightCorner(nw, np) = w.CwQ;
  const double tol = w.s.carry_tolerance * i;
  qp.l.head(kk) = -w.s.tau_max - base_;
  qp.u.head(kk) = w.s.tau_max - base_;
  if (nw) {
    w.cw_base = w.cw_f0;
    w.cw_base.noalias() += w.CwF * base_;
    qp.l.tail(nw) = w.os.lw - w.cw_base;
    qp.u.tail(nw) = w.os.uw - w.cw_base;
  }
  qp.l.array() -= tol;
  qp.u.array() += tol;
  if (qp.has_box) {  // |ẍ* + w| ≤ ẍ_max on the slacks, F_r free
    const auto bound = w.os.acc_bound.segment(w.offsets[i], m);
    qp.lb.head(m) = -bound - ref;
    qp.ub.head(m) = bound - ref;
  }
}

void OsfHqpTick::build_wrench(Set& w) {
  const OsfParams& p = w.params;
  const int kk = k(), L = levels(), nw = w.nw;
  QpBuffers& qp = w.qps.back();
  w.ftask = p.f0;
  w.ftask.noalias() += p.F * tau_;
  w.QW.noalias() = p.Qf.transpose() * w.s.WtW;
  qp.H.noalias() = w.QW * p.Qf;
  qp.H.diagonal().array() += w.s.regularization;
  qp.g.noalias() = w.QW * w.ftask;
  qp.C.topRows(kk) = p.Yc;
  qp.C.bottomRows(nw) = w.CwQ;
  w.cw_base.noalias() = w.s.Cw * w.ftask;
  const double tol = w.s.carry_tolerance * L;
  qp.l.head(kk) = -w.s.tau_max - tau_;
  qp.u.head(kk) = w.s.tau_max - tau_;
  qp.l.tail(nw) = w.os.lw - w.cw_base;
  qp.u.tail(nw) = w.os.uw - w.cw_base;
  qp.l.array() -= tol;
  qp.u.array() += tol;
}

bool OsfHqpTick::level(int i, const Eigen::Ref<const Vector>& x) {
  const auto t0 = Clock::now();
  Set& w = set();
  const int m = w.os.level_dims.at(i);
  if (x.size() != m + w.np) throw std::invalid_argument("osf_hqp: level solution of wrong size");
  tau_ = base_;
  tau_.noalias() += w.params.levels[i].E * x.head(m);
  w.partial.row(i) = tau_.transpose();
  w.slack(i) = x.head(m).norm();
  bool ok = true;
  if (i + 1 < levels()) {
    build_level(w, i + 1);
    ok = w.qps[i + 1].finite();
  } else if (w.np) {
    build_wrench(w);
    ok = w.qps.back().finite();
  }
  times_.build += seconds_since(t0);
  return ok;
}

void OsfHqpTick::finish(const Eigen::Ref<const Vector>& x) {
  const auto t0 = Clock::now();
  Set& w = set();
  if (x.size() != w.np) throw std::invalid_argument("osf_hqp: wrench solution of wrong size");
  dist_.setZero();
  if (w.np) dist_.noalias() = w.params.Yc * x;
  realise(dist_);
  times_.build += seconds_since(t0);
}

}  // namespace wbcbench
