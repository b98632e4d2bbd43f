// OSF-HQP's tick, the native mirror of wbcbench/controllers/osf_hqp.py: one small QP per priority
// level, then a wrench QP.
#pragma once

#include <vector>

#include "controllers/osf.hpp"

namespace wbcbench {

struct OsfHqpSettings : OsfSettings {
  double regularization = 1e-6;
  double carry_tolerance = 1e-6;
  Matrix WtW;                   // W_cᵀ W_c (c, c)
  // dim null(W), the wrench-distribution space: −1 for independent plane contacts (c − 6);
  // contacts with dependent rows (point sets) give it from their rank at the first state
  int distribution = -1;
};

class OsfHqpTick : public OsfTick {
 public:
  using OsfTick::OsfTick;
  // the settings of a contact set: again on a change of the set (after select_contacts), which
  // makes the QPs anew (qp(i) of before then refers to nothing)
  void configure(const OsfHqpSettings& settings);
  void set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                         const Eigen::Ref<const Vector>& uw) override;
  // dynamics, tasks, parameters and the first level's QP; false when the QP holds a NaN or the
  // wrench-distribution space changed dimension (see message())
  bool build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);
  // level i's solution: its torque, then the next QP (a level's, or the wrench QP)
  bool level(int i, const Eigen::Ref<const Vector>& x);
  // the wrench QP's solution (empty when there is none): τ, q̈ and the wrench
  void finish(const Eigen::Ref<const Vector>& x);
  // the QPs: one per level, then the wrench QP where there is a distribution space
  int n_qps() const { return static_cast<int>(qps_.size()); }
  QpBuffers& qp(int i) { return qps_.at(i); }
  const Vector& slack_norms() const { return slack_; }

 private:
  void build_level(int i);
  void build_wrench();

  OsfHqpSettings s_;
  int np_ = 0;
  std::vector<QpBuffers> qps_;
  Vector base_, cw_f0_, slack_, ftask_;
  Matrix CwF_, CwQ_, QW_;
};

}  // namespace wbcbench
