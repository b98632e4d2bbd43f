#include "controllers/osf.hpp"

#include <limits>
#include <stdexcept>

namespace wbcbench {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

OsfInverse parse_inverse(const std::string& name) {
  if (name == "cod") return OsfInverse::kCod;
  if (name == "svd") return OsfInverse::kSvd;
  if (name == "pinv") return OsfInverse::kPinv;
  throw std::invalid_argument("osf: unknown inverse '" + name + "'; valid choices: cod, svd, pinv");
}

}  // namespace

// -- the parameters' part ------------------------------------------------------------------------

void OsfTick::configure_osf(const OsfSettings& s, bool affine) {
  os_ = s;
  const int L = levels();
  if (static_cast<int>(s.force_level.size()) != L)
    throw std::invalid_argument("osf: one force_level flag per level");
  if (s.period < 1) throw std::invalid_argument("osf: period must be ≥ 1");
  offsets_.assign(L, 0);
  nr_ = 0;
  for (int i = 0; i < L; ++i) {
    offsets_[i] = nr_;
    nr_ += s.level_dims[i];
  }
  if (nr_ != tasks_.rows()) throw std::invalid_argument("osf: level dims do not sum to the tasks' rows");
  nc_ = static_cast<int>(dyn_.contact_jacobian().rows());
  nw_ = static_cast<int>(s.Cw.rows());
  if (s.tau_max.size() != k()) throw std::invalid_argument("osf: tau_max of wrong size");
  if (s.Cw.cols() != nc_ || s.lw.size() != nw_ || s.uw.size() != nw_)
    throw std::invalid_argument("osf: wrench constraints of wrong size");
  if (s.acc_bound.size() != nr_) throw std::invalid_argument("osf: one acc_bound per task row");
  OsfModelSpec spec;
  spec.level_dims = s.level_dims;
  spec.force_level = s.force_level;
  spec.inverse = parse_inverse(s.inverse);
  spec.exact = s.exact;
  spec.rcond = s.rcond;
  spec.affine = affine;
  model_ = std::make_unique<OsfModel>(spec);
  worker_.reset();
  if (s.asynchronous)  // made here, so that no tick pays for loading its model
    worker_ = std::make_unique<ParamsWorker>(model_text_, task_frames_, contact_frames_, tasks_,
                                             spec);
  have_params_ = false;
  tick_ = -1;
  partial_.setZero(L, k());
  tau_.setZero(k());
  qdd_.setZero(nv());
  wrench_.setZero(nc_);
}

void OsfTick::evaluate_osf(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                           double t) {
  ++tick_;
  if (os_.asynchronous && have_params_) {
    // the loop's part: publish the state, take the newest complete set
    dyn_.set_inverse(false);
    evaluate(q, v, t);
    const auto t0 = Clock::now();
    worker_->publish(q, v, t, tick_);
    worker_->take_newer(params_);
    times_.params = seconds_since(t0);
    return;
  }
  const bool due = !have_params_ || tick_ - params_.tick >= os_.period;
  dyn_.set_inverse(due);  // M⁻¹ only on the ticks that compute parameters
  evaluate(q, v, t);
  times_.params = 0.0;
  if (due) {
    model_->compute(dyn_, tasks_.J(), tasks_.drift(), tick_, params_);
    have_params_ = true;
    times_.params = params_.compute_time;
    if (worker_) worker_->publish(q, v, t, tick_);  // the worker starts from this state
  }
}

void OsfTick::realise(const Vector& dist) {
  const int L = levels();
  tau_ = dist;
  if (L) tau_ += partial_.row(L - 1).transpose();
  wrench_ = params_.f0;
  wrench_.noalias() += params_.F * tau_;
  qdd_ = params_.qdd0;
  qdd_.noalias() += params_.Phi_a * tau_;
}

// -- TO-OSF ----------------------------------------------------------------------------------

void ToOsfTick::configure(const ToOsfSettings& settings) {
  s_ = settings;
  configure_osf(settings, true);
  if (s_.row_weights.size() != nr_) throw std::invalid_argument("to_osf: one weight per task row");
  if (s_.Sf.cols() != nc_) throw std::invalid_argument("to_osf: Sf of wrong size");
  nx_ = nr_ + nc_;
  h_task_ = s_.row_weights;
  scale_ = nr_ ? 1.0 / h_task_.maxCoeff() : 1.0;
  // F_opt is solved for in units of σ so that both Hessian blocks are O(1)
  w_f_ = (nc_ && s_.wrench_weight > 0) ? scale_ * s_.wrench_weight : scale_;
  const double sigma = 1.0 / std::sqrt(w_f_);
  D_.setOnes(nx_);
  D_.tail(nc_).setConstant(sigma);
  const bool box = (s_.acc_bound.array().abs() < kInf).any();
  qp_.resize(nx_, nc_ ? 6 : 0, k() + static_cast<int>(s_.Cw.rows()), box);
  if (box) {
    qp_.lb.head(nr_) = -s_.acc_bound;
    qp_.ub.head(nr_) = s_.acc_bound;
  }
  Af_.setZero(nc_, nx_);
  Af_.rightCols(nc_).setIdentity();
  rho_.setZero(nr_);
  f_opt_.setZero(nc_);
}

bool ToOsfTick::build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                      double t) {
  const auto t0 = Clock::now();
  evaluate_osf(q, v, t);
  const OsfParams& p = params_;
  const int kk = k();
  const Vector& ref = tasks_.acc_ref();
  // f = A_f x + f_c  (eq. 13)
  Af_.leftCols(nr_).noalias() = p.F * p.K;
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
      qp_.g.noalias() += hw * (SA_.transpose() * (s_.Sf * fc_));
    } else {
      qp_.H.bottomRightCorner(nc_, nc_).noalias() += hw * (s_.Sf.transpose() * s_.Sf);
    }
  }
  qp_.H.bottomRightCorner(nc_, nc_).diagonal().array() += s_.regularization * w_f_;
  if (nc_) {
    qp_.A.rightCols(nc_) = p.G;  // G F_opt = 0 (eq. 14)
  }
  qp_.C.topLeftCorner(kk, nr_) = p.K;
  qp_.C.topRightCorner(kk, nc_) = p.Yw;
  qp_.l.head(kk) = -s_.tau_max - p.gamma0;
  qp_.u.head(kk) = s_.tau_max - p.gamma0;
  if (nc_) {
    qp_.C.bottomRows(nw_).noalias() = s_.Cw * Af_;
    const Vector cwf = s_.Cw * fc_;
    qp_.l.tail(nw_) = s_.lw - cwf;
    qp_.u.tail(nw_) = s_.uw - cwf;
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

void ToOsfTick::finish(const Eigen::Ref<const Vector>& x) {
  const auto t0 = Clock::now();
  if (x.size() != nx_) throw std::invalid_argument("to_osf: solution of wrong size");
  rho_ = x.head(nr_);  // x = D x̃: D is 1 on the references, σ on F_opt
  f_opt_ = x.tail(nc_).cwiseProduct(D_.tail(nc_));
  prev_.setZero(k());
  for (int i = 0; i < levels(); ++i) {
    params_.level_step(i, prev_, rho_.segment(offsets_[i], os_.level_dims[i]), work_);
    partial_.row(i) = work_.transpose();
    prev_ = work_;
  }
  Vector dist = Vector::Zero(k());
  if (nc_) dist.noalias() = params_.Yw * f_opt_;
  realise(dist);
  times_.build += seconds_since(t0);
}

// -- OSF-HQP ---------------------------------------------------------------------------------

void OsfHqpTick::configure(const OsfHqpSettings& settings) {
  s_ = settings;
  configure_osf(settings, false);
  if (s_.WtW.rows() != nc_ || s_.WtW.cols() != nc_)
    throw std::invalid_argument("osf_hqp: WtW of wrong size");
  // the wrench-distribution space of independent plane contacts: dim null(W) = c − 6
  np_ = nc_ > 6 ? nc_ - 6 : 0;
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
  const auto ref = tasks_.acc_ref().segment(offsets_[i], m);
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
    qp.l.tail(nw_) = s_.lw - cwb;
    qp.u.tail(nw_) = s_.uw - cwb;
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
  qp.l.tail(nw_) = s_.lw - cwt;
  qp.u.tail(nw_) = s_.uw - cwt;
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
