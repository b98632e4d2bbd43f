#include "tasks/collision.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace wbcbench {

namespace {

// below this axis-to-axis distance [m] a pair counts as penetrating: its normal is undefined
constexpr double kTouch = 1e-9;

double clip01(double x) { return std::min(std::max(x, 0.0), 1.0); }

}  // namespace

void closest_segment_segment(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1,
                             const Eigen::Vector3d& b0, const Eigen::Vector3d& b1,
                             Eigen::Vector3d& pa, Eigen::Vector3d& pb) {
  const Eigen::Vector3d d1 = a1 - a0, d2 = b1 - b0, r = a0 - b0;
  const double a = d1.dot(d1), e = d2.dot(d2), f = d2.dot(r), c = d1.dot(r), b = d1.dot(d2);
  constexpr double tiny = 1e-15;
  const double a_s = std::max(a, tiny), e_s = std::max(e, tiny);
  const double denom = a * e - b * b;
  // s on segment A for the infinite lines (0 when parallel), then t, then re-clamp s
  // (Ericson, Real-Time Collision Detection, §5.1.9)
  const bool general = denom > 1e-12 * a_s * e_s;
  double s = general ? clip01((b * f - c * e) / denom) : 0.0;
  double t = (b * s + f) / e_s;
  if (t < 0)
    s = clip01(-c / a_s);
  else if (t > 1)
    s = clip01((b - c) / a_s);
  t = clip01(t);
  // degenerate segments (points) have parameter 0
  const bool point_b = e <= tiny, point_a = a <= tiny;
  if (point_b) {
    s = clip01(-c / a_s);
    t = 0.0;
  }
  if (point_a) {
    s = 0.0;
    if (!point_b) t = clip01(f / e_s);
  }
  pa = a0 + s * d1;
  pb = b0 + t * d2;
}

void closest_segment_box(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1,
                         const Eigen::Vector3d& center, const Eigen::Matrix3d& R,
                         const Eigen::Vector3d& half, Eigen::Vector3d& pa, Eigen::Vector3d& pb) {
  const Eigen::Vector3d a = R.transpose() * (a0 - center);  // box-frame coordinates
  const Eigen::Vector3d D = R.transpose() * (a1 - a0);
  // the parameters where the segment crosses a face plane, clipped to [0, 1], with the ends
  std::array<double, 8> ts;
  ts[0] = 0.0;
  ts[7] = 1.0;
  for (int i = 0; i < 3; ++i) {
    const double up = (half[i] - a[i]) / D[i], down = (-half[i] - a[i]) / D[i];
    ts[1 + i] = std::isfinite(up) ? clip01(up) : 0.0;
    ts[4 + i] = std::isfinite(down) ? clip01(down) : 0.0;
  }
  std::sort(ts.begin(), ts.end());
  double best_gap = std::numeric_limits<double>::infinity(), best_t = 0.0;
  for (int k = 0; k < 7; ++k) {
    const double lo = ts[k], hi = ts[k + 1], mid = 0.5 * (lo + hi);
    // on a piece each coordinate stays above, below or inside its slab: clamp target ±h_i
    double num = 0.0, den = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double xm = a[i] + mid * D[i];
      const bool above = xm > half[i], below = xm < -half[i];
      if (!(above || below)) continue;
      const double target = above ? half[i] : -half[i];
      num += D[i] * (a[i] - target);
      den += D[i] * D[i];
    }
    double tstar = den > 1e-300 ? -num / den : mid;
    tstar = std::min(std::max(tstar, lo), hi);
    double gap2 = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double x = a[i] + tstar * D[i];
      const double gap = x - std::min(std::max(x, -half[i]), half[i]);
      gap2 += gap * gap;
    }
    if (gap2 < best_gap) {  // the first piece on ties, as argmin
      best_gap = gap2;
      best_t = tstar;
    }
  }
  const Eigen::Vector3d xs = a + best_t * D;
  const Eigen::Vector3d xb = xs.cwiseMax(-half).cwiseMin(half);
  pa = a0 + best_t * (a1 - a0);
  pb = center + R * xb;
}

void CollisionPairs::configure(int nv, const std::vector<CapsuleSpec>& capsules,
                               const std::vector<std::pair<int, int>>& self_pairs,
                               const std::vector<BoxSpec>& boxes,
                               const std::vector<std::pair<int, int>>& obstacle_pairs) {
  const int nc = static_cast<int>(capsules.size()), nb = static_cast<int>(boxes.size());
  auto check = [](int i, int n, const char* what) {
    if (i < 0 || i >= n)
      throw std::out_of_range(std::string("collision pair: ") + what + " index " +
                              std::to_string(i) + " out of range [0, " + std::to_string(n) + ")");
  };
  for (const auto& [a, b] : self_pairs) {
    check(a, nc, "capsule");
    check(b, nc, "capsule");
  }
  for (const auto& [c, k] : obstacle_pairs) {
    check(c, nc, "capsule");
    check(k, nb, "box");
  }
  capsules_ = capsules;
  boxes_ = boxes;
  self_ = self_pairs;
  obstacle_ = obstacle_pairs;
  w0_.assign(capsules.size(), Eigen::Vector3d::Zero());
  w1_.assign(capsules.size(), Eigen::Vector3d::Zero());
  const Eigen::Index P = static_cast<Eigen::Index>(self_pairs.size() + obstacle_pairs.size());
  d_.setZero(P);
  grad_.setZero(P, nv);
  points_.setZero(P, 6);
  row_.setZero(nv);
}

double CollisionPairs::min_distance() const {
  return d_.size() ? d_.minCoeff() : std::numeric_limits<double>::infinity();
}

void CollisionPairs::add_point_row(int row, int c, const Eigen::Vector3d& p,
                                   const Eigen::Vector3d& n, int sign,
                                   const RobotDynamics& dyn) {
  // nᵀ J_p with J_p = J_v − [p − o]× J_ω:  nᵀ J_v + ((p − o) × n)ᵀ J_ω
  const int f = capsules_[c].frame;
  const Matrix& J = dyn.kinematic_jacobian(f);
  const Eigen::Vector3d lever = (p - Eigen::Vector3d(dyn.kinematic_position(f))).cross(n);
  row_.noalias() = n.transpose() * J.topRows<3>();
  row_.noalias() += lever.transpose() * J.bottomRows<3>();
  if (sign > 0)
    grad_.row(row) += row_;
  else
    grad_.row(row) -= row_;
}

void CollisionPairs::evaluate(const RobotDynamics& dyn) {
  for (size_t i = 0; i < capsules_.size(); ++i) {
    const CapsuleSpec& cap = capsules_[i];
    const Eigen::Matrix3d R = dyn.kinematic_rotation(cap.frame);
    const Eigen::Vector3d o = dyn.kinematic_position(cap.frame);
    w0_[i] = o + R * cap.p0;
    w1_[i] = o + R * cap.p1;
  }
  const int ns = static_cast<int>(self_.size());
  Eigen::Vector3d pa, pb;
  for (int row = 0; row < size(); ++row) {
    double radii;
    int first;
    if (row < ns) {
      const auto [ia, ib] = self_[row];
      closest_segment_segment(w0_[ia], w1_[ia], w0_[ib], w1_[ib], pa, pb);
      radii = capsules_[ia].radius + capsules_[ib].radius;
      first = ia;
    } else {
      const auto [c, k] = obstacle_[row - ns];
      const BoxSpec& box = boxes_[k];
      closest_segment_box(w0_[c], w1_[c], box.center, box.R, box.half, pa, pb);
      radii = capsules_[c].radius;
      first = c;
    }
    const Eigen::Vector3d diff = pb - pa;
    const double axis_dist = diff.norm();
    // penetrating pairs: no direction to move apart along
    const Eigen::Vector3d normal =
        axis_dist < kTouch ? Eigen::Vector3d::Zero() : Eigen::Vector3d(diff / axis_dist);
    d_[row] = axis_dist - radii;
    points_.row(row).head<3>() = pa;
    points_.row(row).tail<3>() = pb;
    grad_.row(row).setZero();
    add_point_row(row, first, pa, normal, -1, dyn);
    if (row < ns) add_point_row(row, self_[row].second, pb, normal, 1, dyn);
  }
}

}  // namespace wbcbench
