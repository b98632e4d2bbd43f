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
  active_.reserve(contact_frames.size());
  for (int i = 0; i < static_cast<int>(contact_frames.size()); ++i) active_.push_back(i);
  contact_points_.assign(contact_frames.size(), Matrix::Zero(0, 3));
  contact_bases_.assign(contact_frames.size(), Matrix::Zero(0, 0));
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

void RobotDynamics::set_contact_points(const std::vector<Matrix>& points,
                                      const std::vector<Matrix>& bases) {
  if (points.size() != impl_->contact_ids.size() || bases.size() != points.size())
    throw std::invalid_argument("set_contact_points: one points and one basis per contact frame");
  int rows = 0, independent = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Matrix& p = points[i];
    if (p.cols() != 3) throw std::invalid_argument("set_contact_points: points are (N, 3)");
    const int m = p.rows() == 0 ? 6 : 3 * static_cast<int>(p.rows());
    if (p.rows() > 0 && bases[i].cols() != m)
      throw std::invalid_argument("set_contact_points: a point set's basis is (r, 3N)");
    rows += m;
    independent += p.rows() == 0 ? 6 : static_cast<int>(bases[i].rows());
  }
  contact_points_ = points;
  contact_bases_ = bases;
  held_.clear();  // sized for the former points
  size_contacts();
}

void RobotDynamics::select_contacts(const std::vector<int>& active) {
  const int n = static_cast<int>(impl_->contact_ids.size());
  for (size_t j = 0; j < active.size(); ++j) {
    if (active[j] < 0 || active[j] >= n || (j > 0 && active[j] <= active[j - 1]))
      throw std::invalid_argument(
          "select_contacts: the active contacts are increasing indices into the " +
          std::to_string(n) + " contact frames");
  }
  if (active == active_) return;
  for (HeldContacts& held : held_) {
    if (held.active == active) {  // the set's own buffers back, the current set's kept instead
      swap_held(held);
      return;
    }
  }
  // a set met for the first time: the current set's buffers are kept, new ones sized
  held_.emplace_back();
  swap_held(held_.back());
  active_.assign(active.begin(), active.end());
  size_contacts();
}

void RobotDynamics::swap_held(HeldContacts& held) {
  active_.swap(held.active);
  J_contact_.swap(held.J_contact);
  J_k_.swap(held.J_k);
  T_.swap(held.T);
  dJv_contact_.swap(held.dJv_contact);
  dJv_k_.swap(held.dJv_k);
  std::swap(redundant_, held.redundant);
}

void RobotDynamics::size_contacts() {
  int rows = 0, independent = 0;
  redundant_ = false;
  for (int i : active_) {
    const Matrix& p = contact_points_[i];
    rows += p.rows() == 0 ? 6 : 3 * static_cast<int>(p.rows());
    independent += p.rows() == 0 ? 6 : static_cast<int>(contact_bases_[i].rows());
    redundant_ = redundant_ || p.rows() > 0;
  }
  J_contact_.setZero(rows, impl_->model.nv);
  dJv_contact_.setZero(rows);
  J_k_.setZero(redundant_ ? independent : 0, impl_->model.nv);
  dJv_k_.setZero(redundant_ ? independent : 0);
  T_.setZero(redundant_ ? independent : 0, redundant_ ? rows : 0);
  for (size_t j = 0, row = 0, out = 0; redundant_ && j < active_.size(); ++j) {
    const Matrix& basis = contact_bases_[active_[j]];
    if (contact_points_[active_[j]].rows() == 0) {
      T_.block(out, row, 6, 6).setIdentity();
      row += 6;
      out += 6;
    } else {
      T_.block(out, row, basis.rows(), basis.cols()) = basis;
      row += basis.cols();
      out += basis.rows();
    }
  }
}

bool RobotDynamics::contact_rows_redundant() const {
  return std::any_of(contact_points_.begin(), contact_points_.end(),
                     [](const Matrix& p) { return p.rows() > 1; });
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
 
  for (size_t a = 0, row = 0; a < active_.size(); ++a) {
    const int i = active_[a];
    const auto fid = impl_->contact_ids[i];
    impl_->jacobian.setZero();
    pin::getFrameJacobian(m, d, fid, pin::LOCAL, impl_->jacobian);
    const pin::Motion acc = pin::getFrameAcceleration(m, d, fid, pin::LOCAL);
    const Matrix& points = contact_points_[i];
    if (points.rows() == 0) {
      J_contact_.middleRows(row, 6) = impl_->jacobian;
      dJv_contact_.segment(row, 6) = acc.toVector();
      row += 6;
      continue;
    }
    // a point p of the frame: v_p = v + ω × p, a_p = a + α × p + ω × (v + ω × p) (classical)
    const pin::Motion vel = pin::getFrameVelocity(m, d, fid, pin::LOCAL);
    const Eigen::Vector3d w = vel.angular();
    for (Eigen::Index j = 0; j < points.rows(); ++j, row += 3) {
      const Eigen::Vector3d p = points.row(j).transpose();
      J_contact_.middleRows(row, 3) = impl_->jacobian.topRows<3>();
      Eigen::Matrix3d p_cross;  // [p]×
      p_cross << 0.0, -p.z(), p.y(), p.z(), 0.0, -p.x(), -p.y(), p.x(), 0.0;
      J_contact_.middleRows(row, 3).noalias() -= p_cross * impl_->jacobian.bottomRows<3>();
      const Eigen::Vector3d vp = vel.linear() + w.cross(p);
      dJv_contact_.segment<3>(row) = acc.linear() + acc.angular().cross(p) + w.cross(vp);
    }
  }
  // the independent rows (RobotState.contact_constraint)
  for (size_t a = 0, row = 0, out = 0; redundant_ && a < active_.size(); ++a) {
    const int i = active_[a];
    if (contact_points_[i].rows() == 0) {
      J_k_.middleRows(out, 6) = J_contact_.middleRows(row, 6);
      dJv_k_.segment(out, 6) = dJv_contact_.segment(row, 6);
      row += 6;
      out += 6;
      continue;
    }
    const Matrix& T = contact_bases_[i];
    J_k_.middleRows(out, T.rows()).noalias() = T * J_contact_.middleRows(row, T.cols());
    dJv_k_.segment(out, T.rows()).noalias() = T * dJv_contact_.segment(row, T.cols());
    row += T.cols();
    out += T.rows();
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
