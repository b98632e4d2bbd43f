#include "controllers/tick.hpp"

#include <stdexcept>

namespace wbcbench {

Tick::Tick(const std::string& model, const std::vector<std::string>& task_frames,
           const std::vector<std::string>& contact_frames)
    : model_text_(model),
      task_frames_(task_frames),
      contact_frames_(contact_frames),
      dyn_(model, task_frames, contact_frames),
      tasks_(dyn_.nv()) {}

void Tick::evaluate(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                    double t) {
  times_.dynamics = dyn_.update(q, v);
  tasks_.evaluate(dyn_, q, v, t);
}

bool Tick::select_contacts(const std::vector<int>& active) {
  if (active == dyn_.active_contacts()) return false;
  dyn_.select_contacts(active);
  return true;
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
