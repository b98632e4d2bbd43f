// Operational-space tasks evaluated every tick: the native mirror of wbcbench/tasks/tasks.py.
// Each task gives its Jacobian J (m, n), drift J̇ q̇ (m,), the PD reference
// ẍ* = ẍ_d + k_p (x_d − x) + k_v (ẋ_d − ẋ), and its error and error rate, stacked over all tasks
// in the order they were added (each task's rows at its offset).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "dynamics/state.hpp"
#include "tasks/trajectory.hpp"

namespace wbcbench {

enum class TaskType { kCom, kFramePosition, kFrameOrientation, kFramePose, kPosture, kDamping };

// One task as the Python side hands it over once its initial value is fixed (Task.start).
struct TaskSpec {
  TaskType type = TaskType::kCom;
  int frame = -1;             // index among RobotDynamics' task frames (frame tasks)
  std::vector<int> rows;      // selected rows of the full task (joint indices for joints)
  Eigen::VectorXd kp, kv;     // per selected row
  bool absolute = false;      // the reference is the target, not an offset from x0
  Eigen::VectorXd x0;         // the full-dimension value at start (zeros for rotations)
  Eigen::Matrix3d R0 = Eigen::Matrix3d::Identity();  // orientation at start
  Trajectory reference;       // of the selected rows
};

class TaskSet {
 public:
  explicit TaskSet(int nv) : nv_(nv) {}

  void add(const TaskSpec& spec);
  int size() const { return static_cast<int>(specs_.size()); }
  int rows() const { return rows_; }
  int offset(int i) const { return offsets_.at(i); }
  int dim(int i) const { return static_cast<int>(specs_.at(i).rows.size()); }
  const TaskSpec& spec(int i) const { return specs_.at(i); }
  // task i's reference value for the next ticks, when it is sampled (Trajectory::sampled):
  // (dim(i),) each, in the task's selected rows
  void set_sample(int i, const Eigen::Ref<const Eigen::VectorXd>& x,
                  const Eigen::Ref<const Eigen::VectorXd>& xd,
                  const Eigen::Ref<const Eigen::VectorXd>& xdd) {
    specs_.at(i).reference.set(x, xd, xdd);
  }

  // Every task at (q, v, t) with the dynamics of that state; allocates nothing.
  void evaluate(const RobotDynamics& dyn, const Eigen::Ref<const Vector>& q,
                const Eigen::Ref<const Vector>& v, double t);

  const Matrix& J() const { return J_; }               // (rows, nv)
  const Vector& drift() const { return drift_; }       // (rows,)
  const Vector& acc_ref() const { return acc_ref_; }   // (rows,)
  const Vector& error() const { return error_; }       // (rows,)
  const Vector& error_vel() const { return error_vel_; }  // (rows,)

 private:
  struct Work {  // per-task buffers of the full dimension
    Vector pos, vel, acc, x_d, xd_d, xdd_d, err;
  };
  int nv_;
  int rows_ = 0;
  std::vector<TaskSpec> specs_;
  std::vector<int> offsets_;
  std::vector<Work> work_;
  Matrix J_;
  Vector drift_, acc_ref_, error_, error_vel_;
};

}  // namespace wbcbench
