// Contact-consistent operational-space parameters (TO-OSF §II and §III-B1, OSF-HQP eq. 16–17):
// the native mirror of wbcbench/dynamics/osf.py, with the same names and conventions (f is the
// contact wrench on the robot, M q̈ + h = Sᵀ Γ + J_cᵀ f). See that module for the equations.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "dynamics/state.hpp"

namespace wbcbench {

enum class OsfInverse { kCod, kSvd, kPinv };

// Y† and the null spaces of a wide (k, n) matrix Y of rank r.
struct Decomposition {
  Matrix pinv;        // (n, k)
  Matrix right_null;  // (n, n − r): TO-OSF's v₂
  Matrix left_null;   // (k, k − r)
  int rank = 0;
};

// Y = Q [T 0; 0 0] Vᵀ by pivoted Householder QR and a QR of the trapezoidal factor.
Decomposition cod(const Matrix& Y, double rcond);
// The same quantities from a full SVD.
Decomposition svd(const Matrix& Y, double rcond);
// X⁺ of a symmetric PSD X and its rank: ranks count the values above rcond · max(largest, scale).
int psd_pinv(const Matrix& X, bool by_svd, double rcond, double scale, Matrix& out);

// One priority level's parameters (m stacked task rows).
struct LevelParams {
  Matrix Jhat;   // Ĵ = J Φ Sᵀ (m, k)
  Vector bias;   // b = J q̈₀ + J̇ q̇ (m,)
  Matrix Jstar;  // J*_{i|<i} (m, k)
  Matrix Lam;    // Λ_{i|<i} (m, m)
  Matrix B;      // J*ᵀ Λ (k, m)
  Matrix E;      // B (acceleration level) or J*ᵀ (force level)
};

// Everything the OSF controllers read each tick (OsfParams in Python).
struct OsfParams {
  std::vector<LevelParams> levels;
  Matrix Phi_a, F, W, Nw, Yc, Qf, Yw, G, K;
  Vector qdd0, f0, gamma0;
  bool exact = true;  // coupling: exact (else literal)
  long tick = 0;
  double compute_time = 0.0;

  // Γ_{≤i} from Γ_{<i} and level i's reference; out may not alias prev
  void level_step(int i, const Vector& prev, const Eigen::Ref<const Vector>& ref,
                  Vector& out) const;
};

// The levels (row blocks of the stacked task Jacobian) and contacts the parameters are for.
struct OsfModelSpec {
  std::vector<int> level_dims;
  std::vector<bool> force_level;  // per level: a force-level (operational force) reference
  OsfInverse inverse = OsfInverse::kCod;
  bool exact = true;
  double rcond = 1e-9;
  bool affine = false;  // also Γ = K ρ + γ₀ over all levels (TO-OSF's single QP)
};

// Computes OsfParams from one tick's dynamics and stacked task Jacobian / drift.
class OsfModel {
 public:
  explicit OsfModel(OsfModelSpec spec) : spec_(std::move(spec)) {}
  const OsfModelSpec& spec() const { return spec_; }
  // dyn must hold M⁻¹ (RobotDynamics::set_inverse(true)); J (Σm, n) and drift (Σm,) are the
  // tasks' rows in level order
  void compute(const RobotDynamics& dyn, const Matrix& J, const Vector& drift, long tick,
               OsfParams& out) const;

 private:
  OsfModelSpec spec_;
};

}  // namespace wbcbench
