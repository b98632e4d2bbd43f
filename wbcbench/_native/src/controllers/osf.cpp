#include "controllers/osf.hpp"

#include <stdexcept>

namespace wbcbench {

namespace {

OsfInverse parse_inverse(const std::string& name) {
  if (name == "cod") return OsfInverse::kCod;
  if (name == "svd") return OsfInverse::kSvd;
  if (name == "pinv") return OsfInverse::kPinv;
  throw std::invalid_argument("osf: unknown inverse '" + name + "'; valid choices: cod, svd, pinv");
}

}  // namespace

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
    worker_ = std::make_unique<ParamsWorker>(model_text_, task_frames_, contact_frames_,
                                             dyn_.contact_points(), dyn_.contact_bases(), tasks_,
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

}  // namespace wbcbench
