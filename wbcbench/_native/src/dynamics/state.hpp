// Per-tick dynamics of one robot, computed once per control tick: the native mirror of
// wbcbench/dynamics/state.py (RobotState). Same conventions: Pinocchio's q and body-frame base
// velocity; task Jacobians and drifts LOCAL_WORLD_ALIGNED, contact ones LOCAL.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "types.hpp"

namespace wbcbench {

// Mirrors RobotState: M, M⁻¹, h, g, the CoM, its Jacobian and drift, the
// centroidal momentum matrix and the Jacobians and drifts of the frames named at set-up.
// Buffers are sized at construction; update() allocates nothing.
class RobotDynamics {
 public:
  // model: Pinocchio's text serialisation of the robot's model (pin.Model.saveToString());
  // task_frames / contact_frames: the frames whose Jacobian and drift every tick needs.
  RobotDynamics(const std::string& model, const std::vector<std::string>& task_frames,
                const std::vector<std::string>& contact_frames);
  ~RobotDynamics();

  // One Pinocchio pass at (q, v); q (nq,), v (nv,). Returns the time it took [s].
  double update(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v);

  int nq() const;
  int nv() const;
  double mass() const;
  std::vector<std::string> joint_names() const;

  // The quantities of the last update(); shapes as in RobotState.
  const Matrix& M() const { return M_; }             // (nv, nv), both triangles
  const Matrix& Minv() const { return Minv_; }       // (nv, nv), by Pinocchio
  const Vector& h() const { return h_; }             // (nv,)
  const Vector& g() const { return g_; }             // (nv,)
  const Vector& com() const { return com_; }         // (3,)
  const Matrix& J_com() const { return Jcom_; }      // (3, nv)
  const Vector& com_drift() const { return acom_; }  // (3,)
  const Matrix& cmm() const { return Ag_; }          // (6, nv)
  const Matrix& task_jacobian(int i) const { return J_task_.at(i); }  // (6, nv)
  const Vector& task_drift(int i) const { return dJv_task_.at(i); }   // (6,)
  const Vector& task_position(int i) const { return p_task_.at(i); }  // (3,) world
  const Matrix& task_rotation(int i) const { return R_task_.at(i); }  // (3, 3) world
  // the active contacts' (select_contacts), stacked in their order
  const Matrix& contact_jacobian() const { return J_contact_; }      // (Σ dim, nv)
  const Vector& contact_drift() const { return dJv_contact_; }       // (Σ dim,)
  // Contacts made of points (RobotState.contact_jacobian with point sets): one (N, 3) matrix
  // per contact frame, the points in the frame, or (0, 3) for a flat contact (6 rows, its
  // LOCAL Jacobian). A point's rows are its linear velocity in the frame's axes (3 rows), its
  // drift the point's classical acceleration at zero q̈. `bases`: per contact, the (r, 3N)
  // orthonormal basis T of its rows' range (dynamics.state.contact_basis), (0, 0) for a flat
  // one. Set-up only: sizes the buffers.
  void set_contact_points(const std::vector<Matrix>& points, const std::vector<Matrix>& bases);
  const std::vector<Matrix>& contact_points() const { return contact_points_; }
  const std::vector<Matrix>& contact_bases() const { return contact_bases_; }
  // The contacts the Jacobians and drifts above hold (Controller.select_contacts): increasing
  // indices into the contact frames; every contact until called. A change gives the contact
  // buffers the active rows (the next update() fills them): a set held before gets its own
  // buffers back (kept since, swapped in: no allocation), a set met for the first time new ones;
  // the same set again does nothing.
  void select_contacts(const std::vector<int>& active);
  const std::vector<int>& active_contacts() const { return active_; }
  // RobotState.contact_constraint: the rows of J_c q̈ + J̇_c q̇ = 0 that are independent by
  // construction (T times a point set's rows; a flat contact's 6); the contact Jacobian and
  // drift themselves when every contact is flat
  const Matrix& constraint_jacobian() const { return redundant_ ? J_k_ : J_contact_; }
  const Vector& constraint_drift() const { return redundant_ ? dJv_k_ : dJv_contact_; }
  // the block-diagonal map (nk, Σ dim) from the contact rows to the independent ones
  // (contact_selector); empty when every contact is flat
  const Matrix& constraint_map() const { return T_; }
  // several points on one frame: the contact rows are dependent by construction
  bool contact_rows_redundant() const;
  // Frames given by Pinocchio id rather than by name (a body that a site of the same name
  // would shadow, as RobotState.placement(frame_id) and RobotState.jacobian(frame_id) read
  // them), whose world placement and world-aligned Jacobian every update() computes (no
  // drift). Set-up only: sizes the buffers.
  void set_kinematic_frames(const std::vector<int>& frame_ids);
  int n_kinematic_frames() const { return static_cast<int>(J_kin_.size()); }
  const Matrix& kinematic_jacobian(int i) const { return J_kin_.at(i); }  // (6, nv)
  const Vector& kinematic_position(int i) const { return p_kin_.at(i); }  // (3,) world
  const Matrix& kinematic_rotation(int i) const { return R_kin_.at(i); }  // (3, 3) world
  // whether update() also computes M⁻¹ (on by default; controllers that never read it turn
  // it off, as RobotState computes it only when asked)
  void set_inverse(bool on) { with_inverse_ = on; }
  bool inverse() const { return with_inverse_; }

  // -- What ReducedDynamics (dynamics/reduced.hpp) needs from Pinocchio, kept here so that
  // Pinocchio's headers stay in state.cpp. The relative passes run on a second Pinocchio Data
  // that this object owns: the first stays as update() left it. Not reentrant: one thread at
  // a time, like update().
  int njoints() const;                              // Pinocchio joints, the universe included
  const Vector& v() const;                          // v of the last update()
  const std::vector<std::string>& contact_frames() const;
  // The summed composite inertia (data.oYcrb after computeAllTerms; computeMinverse then
  // overwrites it, so update() keeps a copy) of the subtrees rooted at `roots` (Pinocchio
  // joint ids) at the last update(): mass [kg], CoM (3,) and rotational inertia about that
  // CoM (3, 3) in world axes. Summed as pin.Inertia's `+`.
  void subtree_inertia(const std::vector<int>& roots, double& mass, Eigen::Vector3d& com,
                       Eigen::Matrix3d& inertia) const;
  // World rotation of joint `joint`'s frame (data.oMi) at the last update().
  Eigen::Matrix3d joint_rotation(int joint) const;
  // Rate of the centroidal momentum [linear; angular] (6,) [N, N·m] about the robot's CoM at
  // the last update()'s q, velocity v_rel (nv,) and zero q̈
  // (computeCentroidalMomentumTimeVariation on the second Data).
  Eigen::Matrix<double, 6, 1> momentum_rate(const Eigen::Ref<const Vector>& v_rel);
  // Nonlinear effects (Coriolis, centrifugal and gravity) (nv,) at the last update()'s q and
  // velocity v_rel: one RNEA on the second Data; the reference is valid until the next call.
  const Vector& nonlinear_effects(const Eigen::Ref<const Vector>& v_rel);

 private:
  struct Impl;  // Pinocchio's model and data: only state.cpp includes Pinocchio
  std::unique_ptr<Impl> impl_;
  Matrix M_, Minv_, Jcom_, Ag_, J_contact_;
  Vector h_, g_, com_, acom_, dJv_contact_;
  std::vector<Matrix> J_task_;
  std::vector<Vector> dJv_task_, p_task_;
  std::vector<Matrix> R_task_;
  std::vector<Matrix> J_kin_, R_kin_;
  std::vector<Matrix> contact_points_;  // per contact: (N, 3), or (0, 3) for a flat one
  std::vector<Matrix> contact_bases_;   // per contact: (r, 3N), or (0, 0) for a flat one
  // sizes the contact buffers and the map T_ for the active contacts
  void size_contacts();
  std::vector<int> active_;             // the active contacts (select_contacts)
  bool redundant_ = false;              // some active contact is a point set
  Matrix J_k_, T_;
  Vector dJv_k_;
  // the contact buffers of the sets held before and not now (select_contacts swaps them in)
  struct HeldContacts {
    std::vector<int> active;
    Matrix J_contact, J_k, T;
    Vector dJv_contact, dJv_k;
    bool redundant = false;
  };
  std::vector<HeldContacts> held_;
  void swap_held(HeldContacts& held);
  std::vector<Vector> p_kin_;
  bool with_inverse_ = true;
};

}  // namespace wbcbench
