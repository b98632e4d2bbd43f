#include "controllers/osf.hpp"

#include <stdexcept>
#include <string>

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
  picked_ = false;
  if (s.tasks.empty()) {
    os_.tasks.resize(tasks_.size());
    for (int i = 0; i < tasks_.size(); ++i) os_.tasks[i] = i;
  }
  int picked_rows = 0;
  for (size_t j = 0; j < os_.tasks.size(); ++j) {
    const int i = os_.tasks[j];
    if (i < 0 || i >= tasks_.size())
      throw std::invalid_argument("osf: task index " + std::to_string(i) + " out of range");
    picked_ = picked_ || i != static_cast<int>(j);
    picked_rows += tasks_.dim(i);
  }
  picked_ = picked_ || static_cast<int>(os_.tasks.size()) != tasks_.size();
  if (nr_ != picked_rows)
    throw std::invalid_argument("osf: level dims do not sum to the level tasks' rows");
  if (picked_ && s.asynchronous)
    throw std::invalid_argument("osf: params async computes with every task; pick none");
  J_.setZero(picked_ ? nr_ : 0, nv());
  drift_.setZero(picked_ ? nr_ : 0);
  ref_.setZero(picked_ ? nr_ : 0);
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
  if (picked_) {  // the level tasks' rows, in level order
    int row = 0;
    for (const int i : os_.tasks) {
      const int m = tasks_.dim(i), from = tasks_.offset(i);
      J_.middleRows(row, m) = tasks_.J().middleRows(from, m);
      drift_.segment(row, m) = tasks_.drift().segment(from, m);
      ref_.segment(row, m) = tasks_.acc_ref().segment(from, m);
      row += m;
    }
  }
  times_.params = 0.0;
  if (due) {
    model_->compute(dyn_, level_J(), level_drift(), tick_, params_);
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
