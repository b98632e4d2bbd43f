// kin_hqp's tick, prioritized kinematic control by regularised reduced QR (RQR-HQP paper,
// §II–IV): the native mirror of KinHqp.build and KinHqp.solve in
// wbcbench/controllers/kin_hqp.py.
//
// Each tick: the dynamics (one Pinocchio pass), the tasks' velocity references
// ẋ_d + λ e (capped), the gaze (eq. 54–55), the support-foot root map, the collision pairs
// (eq. 51–53), the levels — contacts, constraints (joint limits eq. 48–50, the CoM support
// polygon or hold, the collision rows), one level per task priority — written into the
// hierarchy solver's levels in place, the hierarchy solved (src/qp/hls.hpp) and q̇ = T x. The
// levels' shapes are fixed at configure(), so a tick allocates nothing once the solver's
// buffers have grown to the stack.
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <limits>
#include <string>
#include <vector>

#include "controllers/tick.hpp"
#include "qp/hls.hpp"
#include "tasks/collision.hpp"

namespace wbcbench {

// KinHqpConfig.com
enum class KinCom { kPolygon, kFixed, kFree };

// The gaze of KinHqpConfig.gaze (GazeTask): keep `axis` of a frame pointed at `target`.
struct KinGaze {
  bool on = false;
  int frame = -1;  // index among RobotDynamics' kinematic frames
  int axis = 0;    // 0, 1, 2: x, y, z of the frame
  Eigen::Vector3d target = Eigen::Vector3d::Zero();  // world point [m]
  double gain = 1.0;                                 // λ [1/s]
  double speed_limit = std::numeric_limits<double>::infinity();  // cap on ‖λ (v × p)‖ [m/s]
};

// KinHqpConfig and what KinHqp.start fixes, handed over once.
struct KinHqpSettings {
  HlsAlgorithm algorithm = HlsAlgorithm::kReducedQr;
  bool inequalities = true;
  bool support_foot = false;  // base: support_foot (the first contact is the root)
  KinCom com = KinCom::kPolygon;
  double com_gain = 1.0, com_margin = 0.02;       // ξ_c [1/s], polygon shrink [m]
  double joint_limit_gain = 0.5;                  // ξ [1/s]
  double collision_gain = 0.5, collision_margin = 0.005;  // ξ_d [1/s], d_safe [m]
  double damping = 1e-3;                          // Tikhonov factor of the task levels
  Vector q_min, q_max, v_max;                     // (k,) joint limits [rad], [rad/s]
  Eigen::Vector2d com0 = Eigen::Vector2d::Zero(); // horizontal CoM at start [m] (com: fixed)
  RowMatrix polygon_a;  // (E, 2) outward normals of the support polygon (com: polygon)
  Vector polygon_b;     // (E,) offsets: a p ≤ b inside
  Vector speed_limits;  // per task, cap on ‖ẋ_d + λ e‖ (+inf: none)
  KinGaze gaze;
  // the task levels, highest first: the task indices of each (the gaze is index tasks().size())
  std::vector<std::vector<int>> task_levels;
  std::vector<std::string> task_level_names;
};

class KinHqpTick : public Tick {
 public:
  KinHqpTick(const std::string& model, const std::vector<std::string>& task_frames,
             const std::vector<std::string>& contact_frames);

  // Settings, the frames read by id (collision bodies and the gaze frame) and the collision
  // pairs; after the tasks were added. Fixes the levels' shapes.
  void configure(const KinHqpSettings& settings, const std::vector<int>& kinematic_frames,
                 const std::vector<CapsuleSpec>& capsules,
                 const std::vector<std::pair<int, int>>& self_pairs,
                 const std::vector<BoxSpec>& boxes,
                 const std::vector<std::pair<int, int>>& obstacle_pairs);

  // The tick at (q, v, t): build (KinHqp.build) and solve; false when the solver failed
  // (solver().message() says why).
  bool run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);

  const Vector& qd() const { return qd_; }         // (nv,) the command
  const Matrix& root_map() const { return T_; }    // (nv, nx): q̇ = T x
  HlsSolver& solver() { return solver_; }          // the levels of the last tick, its result
  const CollisionPairs& collisions() const { return collisions_; }
  const Vector& references() const { return refs_; }  // (task rows + 3 gaze,) ẋ_d + λ e, capped
  const Matrix& gaze_jacobian() const { return J_gaze_; }  // (3, nv), eq. 55
  const Vector& gaze_error() const { return gaze_error_; }  // (3,) −(v × p)
  double gaze_angle() const { return gaze_angle_; }         // angle between v and p [rad]
  double solve_time() const { return solve_time_; }         // [s]
  int n_eq() const { return n_eq_; }
  int n_ineq() const { return n_ineq_; }  // finite bounds of the last tick
  int n_task() const { return n_task_; }
  int n_x() const { return nx_; }

 private:
  void update_root_map();  // KinHqp._root_map
  void task_rows(const Eigen::Ref<const Vector>& v);  // KinHqp._task_rows
  void gaze();          // GazeTask.evaluate
  // dst = src T (a copy when the base floats: T is the identity)
  template <typename Src, typename Dst>
  void times_root(const Src& src, Dst&& dst) const;

  KinHqpSettings s_;
  CollisionPairs collisions_;
  HlsSolver solver_;
  HlsOptions options_;
  int nx_ = 0, contact_rows_ = 0, contacts_from_ = 0;
  int contacts_level_ = -1, constraints_level_ = -1, first_task_level_ = 0;
  int n_eq_ = 0, n_ineq_ = 0, n_task_ = 0;
  Matrix T_, J_gaze_, Jcom_T_;
  Vector refs_, gaze_error_, qd_, x0_;
  Vector polygon_com_;  // (E,) a c_xy
  double gaze_angle_ = 0.0, solve_time_ = 0.0;
  Eigen::PartialPivLU<Eigen::Matrix<double, 6, 6>> base_lu_;
};

}  // namespace wbcbench
