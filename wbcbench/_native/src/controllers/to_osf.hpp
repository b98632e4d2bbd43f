// TO-OSF's tick, the native mirror of wbcbench/controllers/to_osf.py: one QP over the task
// references and an internal wrench.
#pragma once

#include "controllers/osf.hpp"

namespace wbcbench {

struct ToOsfSettings : OsfSettings {
  Vector row_weights;           // H per task row
  double wrench_weight = 1.0;   // H_w
  bool wrench_total = true;     // S_f on the total wrench (else on F_opt only)
  double regularization = 1e-3;
  Matrix Sf;                    // wrench selection (rows kept, 6c)
};

class ToOsfTick : public OsfTick {
 public:
  using OsfTick::OsfTick;
  void configure(const ToOsfSettings& settings);
  // dynamics, tasks, parameters and the QP; false when the QP holds a NaN
  bool build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);
  // τ, q̈ and the wrench from the QP's solution (scaled variables)
  void finish(const Eigen::Ref<const Vector>& x);
  QpBuffers& qp() { return qp_; }
  const Vector& rho() const { return rho_; }  // the optimised task references

 private:
  ToOsfSettings s_;
  int nx_ = 0;
  double scale_ = 1.0, w_f_ = 1.0;
  Vector D_, h_task_, rho_, f_opt_, fc_, prev_;
  Matrix Af_, SA_;
  QpBuffers qp_;
};

}  // namespace wbcbench
