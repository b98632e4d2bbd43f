// The one translation unit that includes Pinocchio's algorithms (they are costly to compile).
#include "dynamics/state.hpp"

#include <algorithm>
#include <chrono>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/center-of-mass.hpp>
#include <pinocchio/algorithm/centroidal.hpp>
#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>
#include <stdexcept>

namespace wbcbench {

namespace pin = pinocchio;

struct RobotDynamics::Impl {
  pin::Model model;
  std::unique_ptr<pin::Data> data;
  // the second Data: ReducedDynamics' relative passes (momentum_rate, nonlinear_effects)
  std::unique_ptr<pin::Data> relative;
  // data.oYcrb as computeAllTerms leaves it (the composite inertias; computeMinverse
  // overwrites them with the bodies' own)
  decltype(pin::Data::oYcrb) composite;
  std::vector<pin::FrameIndex> task_ids, contact_ids, kinematic_ids;
  std::vector<std::string> contact_names;
  // q, v, a as Pinocchio's own vector type, and a 6×n Jacobian: with these argument types the
  // calls below use libpinocchio_default's precompiled algorithms (other types would
  // instantiate the templates here, unoptimised for the model at hand)
  Vector q, v, a0;
  pin::Data::Matrix6x jacobian;
};

// Mirrors Robot.frame_id: a site (OP_FRAME) of that name, else a body; a joint or a body may
// share a name with a site, so the lookup is by type.
static pin::FrameIndex frame_index(const pin::Model& model, const std::string& name) {
  for (const auto type : {pin::OP_FRAME, pin::BODY}) {
    if (model.existFrame(name, type)) return model.getFrameId(name, type);
  }
  throw std::invalid_argument("unknown frame '" + name + "'");
}

RobotDynamics::RobotDynamics(const std::string& model,
                             const std::vector<std::string>& task_frames,
                             const std::vector<std::string>& contact_frames)
    : impl_(std::make_unique<Impl>()) {
  impl_->model.loadFromString(model);
  const pin::Model& m = impl_->model;
  impl_->data = std::make_unique<pin::Data>(m);
  impl_->relative = std::make_unique<pin::Data>(m);
  impl_->composite = impl_->data->oYcrb;
  impl_->contact_names = contact_frames;
  for (const auto& f : task_frames) impl_->task_ids.push_back(frame_index(m, f));
  for (const auto& f : contact_frames) impl_->contact_ids.push_back(frame_index(m, f));
  const int nv = m.nv;
  const int nc = 6 * static_cast<int>(contact_frames.size());
  impl_->a0 = Vector::Zero(nv);
  impl_->q = Vector::Zero(m.nq);
  impl_->v = Vector::Zero(nv);
  impl_->jacobian = pin::Data::Matrix6x::Zero(6, nv);
  M_.setZero(nv, nv);
  Minv_.setZero(nv, nv);
  Jcom_.setZero(3, nv);
  Ag_.setZero(6, nv);
  J_contact_.setZero(nc, nv);
  h_.setZero(nv);
  g_.setZero(nv);
  com_.setZero(3);
  acom_.setZero(3);
  dJv_contact_.setZero(nc);
  J_task_.assign(task_frames.size(), Matrix::Zero(6, nv));
  dJv_task_.assign(task_frames.size(), Vector::Zero(6));
  p_task_.assign(task_frames.size(), Vector::Zero(3));
  R_task_.assign(task_frames.size(), Matrix::Identity(3, 3));
}

RobotDynamics::~RobotDynamics() = default;

void RobotDynamics::set_kinematic_frames(const std::vector<int>& frame_ids) {
  const pin::Model& m = impl_->model;
  impl_->kinematic_ids.clear();
  for (int id : frame_ids) {
    if (id < 0 || id >= static_cast<int>(m.nframes))
      throw std::out_of_range("frame id " + std::to_string(id) + " out of range [0, " +
                              std::to_string(m.nframes) + ")");
    impl_->kinematic_ids.push_back(static_cast<pin::FrameIndex>(id));
  }
  J_kin_.assign(frame_ids.size(), Matrix::Zero(6, m.nv));
  p_kin_.assign(frame_ids.size(), Vector::Zero(3));
  R_kin_.assign(frame_ids.size(), Matrix::Identity(3, 3));
}

int RobotDynamics::nq() const { return impl_->model.nq; }
int RobotDynamics::nv() const { return impl_->model.nv; }
double RobotDynamics::mass() const { return impl_->data->mass[0]; }

std::vector<std::string> RobotDynamics::joint_names() const {
  return std::vector<std::string>(impl_->model.names.begin(), impl_->model.names.end());
}

int RobotDynamics::njoints() const { return impl_->model.njoints; }
const Vector& RobotDynamics::v() const { return impl_->v; }
const std::vector<std::string>& RobotDynamics::contact_frames() const {
  return impl_->contact_names;
}

static void check_joint(const pin::Model& m, int joint) {
  if (joint < 0 || joint >= m.njoints)
    throw std::out_of_range("joint id " + std::to_string(joint) + " out of range [0, " +
                            std::to_string(m.njoints) + ")");
}

Eigen::Matrix3d RobotDynamics::joint_rotation(int joint) const {
  check_joint(impl_->model, joint);
  return impl_->data->oMi[joint].rotation();
}

void RobotDynamics::subtree_inertia(const std::vector<int>& roots, double& mass,
                                    Eigen::Vector3d& com, Eigen::Matrix3d& inertia) const {
  if (roots.empty()) throw std::invalid_argument("subtree_inertia: no root joint");
  for (int r : roots) check_joint(impl_->model, r);
  const auto& oYcrb = impl_->composite;
  pin::Inertia Y = oYcrb[roots[0]];
  for (size_t i = 1; i < roots.size(); ++i) Y = Y + oYcrb[roots[i]];
  mass = Y.mass();
  com = Y.lever();
  inertia = Y.inertia().matrix();
}

Eigen::Matrix<double, 6, 1> RobotDynamics::momentum_rate(const Eigen::Ref<const Vector>& v_rel) {
  if (v_rel.size() != impl_->model.nv) throw std::invalid_argument("v_rel of wrong size");
  return pin::computeCentroidalMomentumTimeVariation(impl_->model, *impl_->relative, impl_->q,
                                                     v_rel, impl_->a0)
      .toVector();
}

const Vector& RobotDynamics::nonlinear_effects(const Eigen::Ref<const Vector>& v_rel) {
  if (v_rel.size() != impl_->model.nv) throw std::invalid_argument("v_rel of wrong size");
  return pin::nonLinearEffects(impl_->model, *impl_->relative, impl_->q, v_rel);
}

double RobotDynamics::update(const Eigen::Ref<const Vector>& q_in,
                             const Eigen::Ref<const Vector>& v_in) {
  const auto t0 = std::chrono::steady_clock::now();
  const pin::Model& m = impl_->model;
  pin::Data& d = *impl_->data;
  if (q_in.size() != m.nq || v_in.size() != m.nv)
    throw std::invalid_argument("q or v of wrong size");
  impl_->q = q_in;
  impl_->v = v_in;
  const Vector& q = impl_->q;
  const Vector& v = impl_->v;
  // RobotState._terms: kinematics, M, nonlinear effects, gravity, Jacobians, CoM, CMM
  pin::computeAllTerms(m, d, q, v);
  std::copy(d.oYcrb.begin(), d.oYcrb.end(), impl_->composite.begin());
  pin::updateFramePlacements(m, d);
  // RobotState._drifts: second-order kinematics at zero q̈ (data.a) and the CoM drift
  pin::centerOfMass(m, d, q, v, impl_->a0, false);

  M_.triangularView<Eigen::Upper>() = d.M.triangularView<Eigen::Upper>();
  M_.triangularView<Eigen::StrictlyLower>() = M_.transpose().triangularView<Eigen::StrictlyLower>();
  if (with_inverse_) {  // M⁻¹ by Pinocchio's O(n²) pass, as RobotState.Minv
    pin::computeMinverse(m, d, q);
    Minv_.triangularView<Eigen::Upper>() = d.Minv.triangularView<Eigen::Upper>();
    Minv_.triangularView<Eigen::StrictlyLower>() =
        Minv_.transpose().triangularView<Eigen::StrictlyLower>();
  }
 
  h_ = d.nle;
  g_ = d.g;
  com_ = d.com[0];
  Jcom_ = d.Jcom;
  acom_ = d.acom[0];
  Ag_ = d.Ag;
 
  for (size_t i = 0; i < impl_->task_ids.size(); ++i) {
    const auto fid = impl_->task_ids[i];
    impl_->jacobian.setZero();
    pin::getFrameJacobian(m, d, fid, pin::LOCAL_WORLD_ALIGNED, impl_->jacobian);
    J_task_[i] = impl_->jacobian;
    dJv_task_[i] = pin::getFrameClassicalAcceleration(m, d, fid, pin::LOCAL_WORLD_ALIGNED).toVector();
    p_task_[i] = d.oMf[fid].translation();
    R_task_[i] = d.oMf[fid].rotation();
  }
 
  for (size_t i = 0; i < impl_->contact_ids.size(); ++i) {
    const auto fid = impl_->contact_ids[i];
    impl_->jacobian.setZero();
    pin::getFrameJacobian(m, d, fid, pin::LOCAL, impl_->jacobian);
    J_contact_.middleRows(6 * i, 6) = impl_->jacobian;
    dJv_contact_.segment(6 * i, 6) = pin::getFrameAcceleration(m, d, fid, pin::LOCAL).toVector();
  }

  for (size_t i = 0; i < impl_->kinematic_ids.size(); ++i) {
    const auto fid = impl_->kinematic_ids[i];
    impl_->jacobian.setZero();
    pin::getFrameJacobian(m, d, fid, pin::LOCAL_WORLD_ALIGNED, impl_->jacobian);
    J_kin_[i] = impl_->jacobian;
    p_kin_[i] = d.oMf[fid].translation();
    R_kin_[i] = d.oMf[fid].rotation();
  }
 
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace wbcbench
