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
  // the settings of the contact set the tick holds (its workspace's: OsfTick); again for each
  // set, after select_contacts
  void configure(const ToOsfSettings& settings);
  void set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                         const Eigen::Ref<const Vector>& uw) override;
  // dynamics, tasks, parameters and the QP; false when the QP holds a NaN
  bool build(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);
  // τ, q̈ and the wrench from the QP's solution (scaled variables)
  void finish(const Eigen::Ref<const Vector>& x);
  // the QP of the contact set the tick holds
  QpBuffers& qp() { return set().qp; }
  const Vector& rho() const { return set().rho; }  // the optimised task references

 private:
  // a contact set's settings, QP and the buffers its sizes fix
  struct Set : OsfWorkspace {
    ToOsfSettings s;
    int nx = 0, nf = 0;   // variables; F_opt's part of them (c, or c − 6 with a basis)
    bool basis = false;   // this configuration parametrises F_opt by a basis N
    Matrix N;
    double scale = 1.0, w_f = 1.0;
    Vector D, h_task, rho, f_opt, fc, x_f;  // … x_f: F_opt's variables in their units
    Vector sf_fc, cw_fc, qf_f;  // S_f f_c, C_w f_c, Q_fᵀ F_opt
    Matrix Af, SA;
    QpBuffers qp;
  };
  std::unique_ptr<OsfWorkspace> make_workspace() const override {
    return std::make_unique<Set>();
  }
  Set& set() { return static_cast<Set&>(w()); }
  const Set& set() const { return static_cast<const Set&>(w()); }
  // N: wbcbench.controllers.to_osf.internal_basis of the parameters' G; false when there is none
  bool internal_basis(Set& w);

  // G's first contact block (6 × 6: fixed-size, on the stack)
  Eigen::PartialPivLU<Eigen::Matrix<double, 6, 6>> lu_;
  Vector prev_, step_, dist_;  // (k,): Γ_{<i}, Γ_{≤i}, Y_w F_opt
};

}  // namespace wbcbench
