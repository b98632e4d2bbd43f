#include "controllers/tick.hpp"

#include <algorithm>
#include <stdexcept>

namespace wbcbench {

Tick::Tick(const std::string& model, const std::vector<std::string>& task_frames,
           const std::vector<std::string>& contact_frames)
    : model_text_(model),
      task_frames_(task_frames),
      contact_frames_(contact_frames),
      dyn_(model, task_frames, contact_frames),
      tasks_(dyn_.nv()) {
  sets_.push_back(dyn_.active_contacts());
}

void Tick::evaluate(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                    double t) {
  times_.dynamics = dyn_.update(q, v);
  tasks_.evaluate(dyn_, q, v, t);
}

bool Tick::select_contacts(const std::vector<int>& active) {
  if (active == dyn_.active_contacts()) return false;
  dyn_.select_contacts(active);
  const auto it = std::find(sets_.begin(), sets_.end(), active);
  set_ = static_cast<int>(it - sets_.begin());
  if (it == sets_.end()) sets_.push_back(active);
  contacts_switched(set_);
  return true;
}

bool Tick::switch_contacts(int set) {
  if (set < 0 || set >= contact_sets())
    throw std::out_of_range("switch_contacts: no contact set number " + std::to_string(set) +
                            " (the tick has held " + std::to_string(contact_sets()) + ")");
  return select_contacts(sets_[static_cast<size_t>(set)]);
}

void Tick::set_wrench_bounds(const Eigen::Ref<const Vector>&, const Eigen::Ref<const Vector>&) {
  throw std::logic_error("this controller's native tick holds a fixed contact set");
}

void check_wrench_bounds(const char* controller, const Matrix& Cw,
                         const Eigen::Ref<const Vector>& lw, const Eigen::Ref<const Vector>& uw) {
  if (lw.size() != Cw.rows() || uw.size() != Cw.rows())
    throw std::invalid_argument(std::string(controller) + ": wrench bounds of " +
                                std::to_string(lw.size()) + " and " + std::to_string(uw.size()) +
                                " rows; the contact set has " + std::to_string(Cw.rows()));
}

}  // namespace wbcbench
