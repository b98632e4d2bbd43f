#include "controllers/tick.hpp"

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

}  // namespace wbcbench
