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
  // the settings of the contact set the tick holds (its workspace's: OsfTick); again for each
  // set, after select_contacts. Configuring a set again makes its QPs anew (its qp(i) of before
  // then refers to nothing); a switch to a set configured before keeps them.
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
  // the QPs of the contact set the tick holds: one per level, then the wrench QP where there
  // is a distribution space
  int n_qps() const { return static_cast<int>(set().qps.size()); }
  QpBuffers& qp(int i) { return set().qps.at(i); }
  const Vector& slack_norms() const { return set().slack; }

 private:
  // a contact set's settings, QPs and the buffers its sizes fix
  struct Set : OsfWorkspace {
    OsfHqpSettings s;
    int np = 0;
    std::vector<QpBuffers> qps;
    Vector cw_f0, slack, ftask, cw_base;  // C_w f₀, ‖w_i‖, f of the levels' torque, C_w (f₀ + F Γ)
    Matrix CwF, CwQ, QW;
  };
  std::unique_ptr<OsfWorkspace> make_workspace() const override {
    return std::make_unique<Set>();
  }
  Set& set() { return static_cast<Set&>(w()); }
  const Set& set() const { return static_cast<const Set&>(w()); }
  void build_level(Set& w, int i);
  void build_wrench(Set& w);

  Vector base_, dist_;  // (k,): Γ_{≤l} with w_l = 0; Y_c F_r
};

}  // namespace wbcbench
