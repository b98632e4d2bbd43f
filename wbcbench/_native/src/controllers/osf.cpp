#include "controllers/osf.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>

namespace wbcbench {

namespace {

OsfInverse parse_inverse(const std::string& name) {
  if (name == "cod") return OsfInverse::kCod;
  if (name == "svd") return OsfInverse::kSvd;
  if (name == "pinv") return OsfInverse::kPinv;
  throw std::invalid_argument("osf: unknown inverse '" + name + "'; valid choices: cod, svd, pinv");
}

}  // namespace

OsfWorkspace& OsfTick::w() {
  if (w_ == nullptr)
    throw std::logic_error("osf: the tick's contact set is not configured (configure first)");
  return *w_;
}

const OsfWorkspace& OsfTick::w() const {
  if (w_ == nullptr)
    throw std::logic_error("osf: the tick's contact set is not configured (configure first)");
  return *w_;
}

void OsfTick::contacts_switched(int set) {
  const auto i = static_cast<size_t>(set);
  w_ = i < work_.size() ? work_[i].get() : nullptr;
  // the set's parameters (and its worker's) are of a state before the switch: the next tick
  // computes them afresh
  if (w_ != nullptr) w_->have_params = false;
}

long OsfTick::worker_sets() const {
  long n = 0;
  for (const auto& w : work_)
    if (w && w->worker) n += w->worker->computed();
  return n;
}

void OsfTick::close() {
  for (const auto& w : work_)
    if (w) w->worker.reset();
}

void OsfTick::configure_osf(const OsfSettings& s, bool affine) {
  const int L = static_cast<int>(s.level_dims.size());
  if (static_cast<int>(s.force_level.size()) != L)
    throw std::invalid_argument("osf: one force_level flag per level");
  if (s.period < 1) throw std::invalid_argument("osf: period must be ≥ 1");
  std::vector<int> tasks = s.tasks;
  if (tasks.empty()) {
    tasks.resize(tasks_.size());
    for (int i = 0; i < tasks_.size(); ++i) tasks[i] = i;
  }
  int nr = 0, widest = 0;
  std::vector<int> offsets(L, 0);
  for (int i = 0; i < L; ++i) {
    offsets[i] = nr;
    nr += s.level_dims[i];
    widest = std::max(widest, s.level_dims[i]);
  }
  bool picked = false;
  int picked_rows = 0;
  for (size_t j = 0; j < tasks.size(); ++j) {
    const int i = tasks[j];
    if (i < 0 || i >= tasks_.size())
      throw std::invalid_argument("osf: task index " + std::to_string(i) + " out of range");
    picked = picked || i != static_cast<int>(j);
    picked_rows += tasks_.dim(i);
  }
  picked = picked || static_cast<int>(tasks.size()) != tasks_.size();
  if (nr != picked_rows)
    throw std::invalid_argument("osf: level dims do not sum to the level tasks' rows");
  if (picked && s.asynchronous)
    throw std::invalid_argument("osf: params async computes with every task; pick none");
  const int nc = static_cast<int>(dyn_.contact_jacobian().rows());
  const int nw = static_cast<int>(s.Cw.rows());
  if (s.tau_max.size() != k()) throw std::invalid_argument("osf: tau_max of wrong size");
  if (s.Cw.cols() != nc || s.lw.size() != nw || s.uw.size() != nw)
    throw std::invalid_argument("osf: wrench constraints of wrong size");
  if (s.acc_bound.size() != nr) throw std::invalid_argument("osf: one acc_bound per task row");
  OsfModelSpec spec;
  spec.level_dims = s.level_dims;
  spec.force_level = s.force_level;
  spec.inverse = parse_inverse(s.inverse);
  spec.exact = s.exact;
  spec.rcond = s.rcond;
  spec.affine = affine;

  const auto set = static_cast<size_t>(set_);
  if (work_.size() <= set) work_.resize(set + 1);
  if (!work_[set]) work_[set] = make_workspace();
  OsfWorkspace& w = *(w_ = work_[set].get());
  w.worker.reset();
  w.os = s;
  w.os.tasks = std::move(tasks);
  w.offsets = std::move(offsets);
  w.nr = nr;
  w.nc = nc;
  w.nw = nw;
  w.picked = picked;
  w.J.setZero(picked ? nr : 0, nv());
  w.drift.setZero(picked ? nr : 0);
  w.ref.setZero(picked ? nr : 0);
  w.model = std::make_unique<OsfModel>(spec);
  if (s.asynchronous)  // made here, so that no tick pays for loading its model
    w.worker = std::make_unique<ParamsWorker>(model_text_, task_frames_, contact_frames_,
                                              dyn_.contact_points(), dyn_.contact_bases(),
                                              dyn_.active_contacts(), tasks_, spec);
  w.have_params = false;
  w.partial.setZero(L, k());
  w.wrench.setZero(nc);
  w.level_work.setZero(widest);
  tau_.setZero(k());
  qdd_.setZero(nv());
}

void OsfTick::prepare(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                      double t) {
  OsfWorkspace& w = this->w();
  dyn_.set_inverse(true);
  evaluate(q, v, t);
  gather(w);
  w.model->compute(dyn_, level_J(), level_drift(), w.params.tick, w.params);
  w.have_params = false;
}

void OsfTick::gather(OsfWorkspace& w) {
  if (!w.picked) return;
  int row = 0;
  for (const int i : w.os.tasks) {
    const int m = tasks_.dim(i), from = tasks_.offset(i);
    w.J.middleRows(row, m) = tasks_.J().middleRows(from, m);
    w.drift.segment(row, m) = tasks_.drift().segment(from, m);
    w.ref.segment(row, m) = tasks_.acc_ref().segment(from, m);
    row += m;
  }
}

void OsfTick::evaluate_osf(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                           double t) {
  ++tick_;
  OsfWorkspace& w = this->w();
  if (w.os.asynchronous && w.have_params) {
    // the loop's part: publish the state, take the newest complete set (one of this contact
    // set's worker computed from a state published since the tick last switched here: an older
    // one is refused, its tick not newer than the set computed at the switch)
    dyn_.set_inverse(false);
    evaluate(q, v, t);
    const auto t0 = Clock::now();
    w.worker->publish(q, v, t, tick_);
    w.worker->take_newer(w.params);
    times_.params = seconds_since(t0);
    return;
  }
  const bool due = !w.have_params || tick_ - w.params.tick >= w.os.period;
  dyn_.set_inverse(due);  // M⁻¹ only on the ticks that compute parameters
  evaluate(q, v, t);
  gather(w);
  times_.params = 0.0;
  if (due) {
    w.model->compute(dyn_, level_J(), level_drift(), tick_, w.params);
    w.have_params = true;
    times_.params = w.params.compute_time;
    if (w.worker) w.worker->publish(q, v, t, tick_);  // the worker starts from this state
  }
}

void OsfTick::realise(const Vector& dist) {
  OsfWorkspace& w = this->w();
  const OsfParams& p = w.params;
  const int L = levels();
  tau_ = dist;
  if (L) tau_ += w.partial.row(L - 1).transpose();
  w.wrench = p.f0;
  w.wrench.noalias() += p.F * tau_;
  qdd_ = p.qdd0;
  qdd_.noalias() += p.Phi_a * tau_;
}

}  // namespace wbcbench
