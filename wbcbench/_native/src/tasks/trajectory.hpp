// Reference trajectories sampled every tick: the native mirror of
// wbcbench/tasks/trajectories.py. The Python side hands each one over once, as its kind and
// the numbers that define it (for a cubic spline: SciPy's breakpoints and coefficients).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace wbcbench {

class Trajectory {
 public:
  enum class Kind { kConstant, kSinusoid, kCubic, kMinimumJerk, kLinear, kSampled };

  // constant: value (dim,)
  static Trajectory constant(const Eigen::VectorXd& value);
  // x = a sin(2π f (t − t0) + φ) − a sin φ for t ≥ t0, zero before
  static Trajectory sinusoid(const Eigen::VectorXd& amplitude, double frequency, double t0,
                             double phase);
  // C² cubic pieces: breaks (s+1,), coef (4·s, dim) = SciPy's c[(power), segment, :] stacked
  // power-major (row 4·i + p holds power 3 − p of segment i), held outside the breaks
  static Trajectory cubic(const std::vector<double>& breaks, const Eigen::MatrixXd& coef,
                          const Eigen::VectorXd& first, const Eigen::VectorXd& last);
  // waypoints (times (w,), values (w, dim)) joined by quintic minimum-jerk or linear pieces
  static Trajectory waypoints(Kind kind, const std::vector<double>& times,
                              const Eigen::MatrixXd& values);

  // a reference with no native form (a walk's CoM plan, heading or swing path): the Python
  // side samples it and hands (x, ẋ, ẍ) over before each tick (set); zeros until then
  static Trajectory sampled(int dim);
  // a sampled trajectory's value for the next ticks, (dim,) each; allocates nothing
  void set(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::VectorXd>& xd,
           const Eigen::Ref<const Eigen::VectorXd>& xdd);

  int dim() const { return dim_; }
  // (x, ẋ, ẍ) at t into the given (dim,) outputs; allocates nothing
  void sample(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> xd,
              Eigen::Ref<Eigen::VectorXd> xdd) const;

 private:
  // the piece of a breakpoint list that contains t (bisect_right − 1); t strictly inside
  int piece(double t) const;

  Kind kind_ = Kind::kConstant;
  int dim_ = 0;
  Eigen::VectorXd value_, amplitude_, first_, last_;
  Eigen::VectorXd rate_, acceleration_;  // a sampled trajectory's ẋ and ẍ
  double frequency_ = 0.0, t0_ = 0.0, phase_ = 0.0;
  std::vector<double> times_;
  Eigen::MatrixXd table_;  // cubic coefficients or waypoint values
};

}  // namespace wbcbench
