// Capsule and box distances with their Jacobians, for collision-avoidance inequalities: the
// native mirror of wbcbench/tasks/collision.py (RQR-HQP paper §IV-B, eq. 51–53).
//
// Every checked pair gives its surface distance d (the distance between the capsules' axes, or
// between a capsule's axis and a box, minus the radii) and the gradient row ḋ = grad q̇,
// grad = nᵀ (J_2 − J_1) with n the unit vector between the closest points and J_i the
// world Jacobian of the point moving with its body (J_2 = 0 for a fixed box). The same
// formulas, in the same order, as the vectorised Python, one pair at a time.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "dynamics/state.hpp"
#include "types.hpp"

namespace wbcbench {

// Closest points pa on segment a0a1 and pb on segment b0b1 (closest_segment_segment).
// Parallel segments get one of the closest pairs; a degenerate segment (a point) has
// parameter 0.
void closest_segment_segment(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1,
                             const Eigen::Vector3d& b0, const Eigen::Vector3d& b1,
                             Eigen::Vector3d& pa, Eigen::Vector3d& pb);

// Closest points pa on segment a0a1 and pb of the box (centre, rotation R whose columns are the
// box axes, half sizes), world frame (closest_segment_box): the squared distance along the
// segment is convex and piecewise quadratic, broken where the segment crosses a face plane;
// each piece is minimised in closed form and the best kept. A segment through the box gets a
// point inside it for both.
void closest_segment_box(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1,
                         const Eigen::Vector3d& center, const Eigen::Matrix3d& R,
                         const Eigen::Vector3d& half, Eigen::Vector3d& pa, Eigen::Vector3d& pb);

// A capsule fixed to a body (collision.Capsule): the segment p0–p1 in the body frame [m] swept
// by a ball of `radius` [m]; `frame` indexes RobotDynamics' kinematic frames.
struct CapsuleSpec {
  int frame = -1;
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero(), p1 = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

// A fixed box obstacle (collision.Box): world centre, rotation (columns: the box axes) and half
// sizes [m].
struct BoxSpec {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d half = Eigen::Vector3d::Zero();
};

// The pairs of collision.CollisionModel, self pairs first, then the capsule–box pairs, in the
// order the Python model lists them; set up once, evaluated every tick without allocating.
class CollisionPairs {
 public:
  // capsules: the model's bodies; self_pairs: (capsule, capsule); obstacle_pairs: (capsule,
  // box). Indices are checked.
  void configure(int nv, const std::vector<CapsuleSpec>& capsules,
                 const std::vector<std::pair<int, int>>& self_pairs,
                 const std::vector<BoxSpec>& boxes,
                 const std::vector<std::pair<int, int>>& obstacle_pairs);
  int size() const { return static_cast<int>(d_.size()); }

  // CollisionModel.evaluate at the dynamics' last update.
  void evaluate(const RobotDynamics& dyn);

  const Vector& d() const { return d_; }          // (P,) surface distances [m]
  const Matrix& grad() const { return grad_; }    // (P, nv): ḋ = grad q̇
  const Matrix& points() const { return points_; }  // (P, 6): [P_1, P_2] world [m]
  double min_distance() const;                    // +inf without pairs

 private:
  // adds (sign ±1) nᵀ J_p = nᵀ J_v + ((p − o) × n)ᵀ J_ω, the rate of the world point p moving
  // with capsule c's body along n, to grad row `row`
  void add_point_row(int row, int c, const Eigen::Vector3d& p, const Eigen::Vector3d& n,
                     int sign, const RobotDynamics& dyn);

  std::vector<CapsuleSpec> capsules_;
  std::vector<BoxSpec> boxes_;
  std::vector<std::pair<int, int>> self_, obstacle_;
  std::vector<Eigen::Vector3d> w0_, w1_;  // capsule axes' end points in the world
  Vector d_;
  Matrix grad_, points_;
  Eigen::RowVectorXd row_;  // (nv,) one point's row
};

}  // namespace wbcbench
