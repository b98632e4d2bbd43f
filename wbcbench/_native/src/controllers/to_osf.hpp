// TO-OSF's tick, the native mirror of wbcbench/controllers/to_osf.py: one QP over the task
// references and an internal wrench.
#pragma once

#include <Eigen/LU>

#include "controllers/osf.hpp"

namespace wbcbench {

struct ToOsfSettings : OsfSettings {
  Vector row_weights;           // H per task row
  double wrench_weight = 1.0;   // H_w
  bool wrench_total = true;     // S_f on the total wrench (else on F_opt only)
  double regularization = 1e-3;
  Matrix Sf;                    // wrench selection (rows kept, 6c)
  bool internal_basis = true;   // F_opt = N w over a basis of G's null space (else G F_opt = 0)
};

class ToOsfTick : public OsfTick {
 public:
  using OsfTick::OsfTick;
  // the settings of a contact set: again on a change of the set (after select_contacts)
  void configure(const ToOsfSettings& settings);
  void set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                         const Eigen::Ref<const Vector>& uw) override;
  // dynamics, tasks, parameters and the QP; false when the QP holds a NaN
  bool build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);
  // τ, q̈ and the wrench from the QP's solution (scaled variables)
  void finish(const Eigen::Ref<const Vector>& x);
  QpBuffers& qp() { return qp_; }
  const Vector& rho() const { return rho_; }  // the optimised task references

 private:
  // N: wbcbench.controllers.to_osf.internal_basis of params_.G; false when there is none
  bool internal_basis();

  ToOsfSettings s_;
  int nx_ = 0, nf_ = 0;   // variables; F_opt's part of them (c, or c − 6 with a basis)
  bool basis_ = false;    // this configuration parametrises F_opt by a basis N
  Matrix N_;
  Eigen::PartialPivLU<Matrix> lu_;  // of G's first contact block
  double scale_ = 1.0, w_f_ = 1.0;
  Vector D_, h_task_, rho_, f_opt_, fc_, prev_;
  Vector sf_fc_, cw_fc_, dist_, qf_f_;  // S_f f_c, C_w f_c, Y_w F_opt, Q_fᵀ F_opt
  Matrix Af_, SA_;
  QpBuffers qp_;
};

}  // namespace wbcbench
