#include "controllers/tick.hpp"

namespace wbcbench {

void QpBuffers::resize(int n, int n_eq, int n_in, bool box) {
  H.setZero(n, n);
  g.setZero(n);
  A.setZero(n_eq, n);
  b.setZero(n_eq);
  C.setZero(n_in, n);
  l.setZero(n_in);
  u.setZero(n_in);
  has_box = box;
  lb.setConstant(box ? n : 0, -std::numeric_limits<double>::infinity());
  ub.setConstant(box ? n : 0, std::numeric_limits<double>::infinity());
}

bool QpBuffers::finite() const {
  const auto no_nan = [](const Vector& x) { return !x.hasNaN(); };
  return H.allFinite() && g.allFinite() && A.allFinite() && b.allFinite() && C.allFinite() &&
         no_nan(l) && no_nan(u) && no_nan(lb) && no_nan(ub);
}

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
