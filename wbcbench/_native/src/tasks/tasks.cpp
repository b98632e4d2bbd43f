#include "tasks/tasks.hpp"

#include <Eigen/Geometry>
#include <stdexcept>

namespace wbcbench {

namespace {

int full_dim(TaskType type, int k) {
  switch (type) {
    case TaskType::kCom:
    case TaskType::kFramePosition:
    case TaskType::kFrameOrientation:
      return 3;
    case TaskType::kFramePose:
      return 6;
    default:
      return k;
  }
}

// exp3 of a rotation vector (Pinocchio's pin.exp3)
Eigen::Matrix3d exp3(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-300) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

// log3 of a rotation matrix (Pinocchio's pin.log3): the rotation vector in [0, π]
Eigen::Vector3d log3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

}  // namespace

void TaskSet::add(const TaskSpec& spec) {
  const int k = nv_ - 6;
  const int full = full_dim(spec.type, k);
  const int m = static_cast<int>(spec.rows.size());
  if (spec.kp.size() != m || spec.kv.size() != m || spec.reference.dim() != m)
    throw std::invalid_argument("task: gains and reference must have one entry per row");
  if (spec.x0.size() != full) throw std::invalid_argument("task: initial value of wrong size");
  for (int r : spec.rows)
    if (r < 0 || r >= full) throw std::invalid_argument("task: row out of range");
  const bool framed = spec.type == TaskType::kFramePosition ||
                      spec.type == TaskType::kFrameOrientation ||
                      spec.type == TaskType::kFramePose;
  if (framed && spec.frame < 0) throw std::invalid_argument("task: frame task without a frame");
  specs_.push_back(spec);
  offsets_.push_back(rows_);
  rows_ += m;
  Work w;
  w.pos.setZero(m);
  w.vel.setZero(m);
  w.acc.setZero(m);
  w.x_d.setZero(full);
  w.xd_d.setZero(full);
  w.xdd_d.setZero(full);
  w.err.setZero(full);
  work_.push_back(std::move(w));
  J_.setZero(rows_, nv_);
  drift_.setZero(rows_);
  acc_ref_.setZero(rows_);
  error_.setZero(rows_);
  error_vel_.setZero(rows_);
}

void TaskSet::evaluate(const RobotDynamics& dyn, const Eigen::Ref<const Vector>& q,
                       const Eigen::Ref<const Vector>& v, double t) {
  for (size_t i = 0; i < specs_.size(); ++i) {
    const TaskSpec& s = specs_[i];
    Work& w = work_[i];
    const int o = offsets_[i];
    const int m = static_cast<int>(s.rows.size());
    auto J = J_.middleRows(o, m);
    auto drift = drift_.segment(o, m);
    auto err = error_.segment(o, m);
    auto err_vel = error_vel_.segment(o, m);
    auto ref = acc_ref_.segment(o, m);

    if (s.type == TaskType::kDamping) {  // ẍ* = −k_v q̇ on the selected joints
      for (int r = 0; r < m; ++r) {
        const double qd = v[6 + s.rows[r]];
        J.row(r).setZero();
        J(r, 6 + s.rows[r]) = 1.0;
        drift[r] = 0.0;
        err[r] = 0.0;
        err_vel[r] = -qd;
        ref[r] = -s.kv[r] * qd;
      }
      continue;
    }

    // the desired value, rate and acceleration of the full task (Task.desired)
    s.reference.sample(t, w.pos, w.vel, w.acc);
    w.x_d = s.x0;
    w.xd_d.setZero();
    w.xdd_d.setZero();
    for (int r = 0; r < m; ++r) {
      const int row = s.rows[r];
      w.x_d[row] = s.absolute ? w.pos[r] : w.x_d[row] + w.pos[r];
      w.xd_d[row] = w.vel[r];
      w.xdd_d[row] = w.acc[r];
    }

    // Jacobian, drift and error of the full task, then the selected rows
    switch (s.type) {
      case TaskType::kCom:
        for (int r = 0; r < m; ++r) {
          J.row(r) = dyn.J_com().row(s.rows[r]);
          drift[r] = dyn.com_drift()[s.rows[r]];
        }
        w.err = w.x_d - dyn.com();
        break;
      case TaskType::kFramePosition:
      case TaskType::kFrameOrientation:
      case TaskType::kFramePose: {
        const int base = s.type == TaskType::kFrameOrientation ? 3 : 0;
        const Matrix& Jf = dyn.task_jacobian(s.frame);
        const Vector& af = dyn.task_drift(s.frame);
        for (int r = 0; r < m; ++r) {
          J.row(r) = Jf.row(base + s.rows[r]);
          drift[r] = af[base + s.rows[r]];
        }
        const Vector& p = dyn.task_position(s.frame);
        if (s.type == TaskType::kFramePosition) {
          w.err = w.x_d - p;
          break;
        }
        const int rot = s.type == TaskType::kFramePose ? 3 : 0;
        const Eigen::Vector3d offset = w.x_d.segment<3>(rot);
        const Eigen::Matrix3d target = s.absolute ? exp3(offset) : Eigen::Matrix3d(exp3(offset) * s.R0);
        const Eigen::Matrix3d R = dyn.task_rotation(s.frame);
        w.err.segment<3>(rot) = log3(target * R.transpose());
        if (rot) w.err.head<3>() = w.x_d.head<3>() - p;
        break;
      }
      case TaskType::kPosture:
        for (int r = 0; r < m; ++r) {
          J.row(r).setZero();
          J(r, 6 + s.rows[r]) = 1.0;
          drift[r] = 0.0;
        }
        w.err = w.x_d - q.tail(nv_ - 6);
        break;
      case TaskType::kDamping:
        break;
    }
    for (int r = 0; r < m; ++r) {
      const int row = s.rows[r];
      err[r] = w.err[row];
      err_vel[r] = w.xd_d[row] - J.row(r).dot(v);
      ref[r] = w.xdd_d[row] + s.kp[r] * err[r] + s.kv[r] * err_vel[r];
    }
  }
}

}  // namespace wbcbench
