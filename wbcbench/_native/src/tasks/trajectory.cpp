#include "tasks/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace wbcbench {

Trajectory Trajectory::constant(const Eigen::VectorXd& value) {
  Trajectory out;
  out.kind_ = Kind::kConstant;
  out.dim_ = static_cast<int>(value.size());
  out.value_ = value;
  return out;
}

Trajectory Trajectory::sinusoid(const Eigen::VectorXd& amplitude, double frequency, double t0,
                                double phase) {
  Trajectory out;
  out.kind_ = Kind::kSinusoid;
  out.dim_ = static_cast<int>(amplitude.size());
  out.amplitude_ = amplitude;
  out.frequency_ = frequency;
  out.t0_ = t0;
  out.phase_ = phase;
  return out;
}

Trajectory Trajectory::cubic(const std::vector<double>& breaks, const Eigen::MatrixXd& coef,
                             const Eigen::VectorXd& first, const Eigen::VectorXd& last) {
  const auto segments = static_cast<Eigen::Index>(breaks.size()) - 1;
  if (segments < 1 || coef.rows() != 4 * segments || first.size() != coef.cols() ||
      last.size() != coef.cols())
    throw std::invalid_argument("cubic trajectory: breaks, coefficients and ends disagree");
  Trajectory out;
  out.kind_ = Kind::kCubic;
  out.dim_ = static_cast<int>(coef.cols());
  out.times_ = breaks;
  out.table_ = coef;
  out.first_ = first;
  out.last_ = last;
  return out;
}

Trajectory Trajectory::waypoints(Kind kind, const std::vector<double>& times,
                                 const Eigen::MatrixXd& values) {
  if (kind != Kind::kMinimumJerk && kind != Kind::kLinear)
    throw std::invalid_argument("waypoint trajectories are minimum-jerk or linear");
  if (times.empty() || values.rows() != static_cast<Eigen::Index>(times.size()))
    throw std::invalid_argument("waypoint trajectory: times and values disagree");
  Trajectory out;
  out.kind_ = kind;
  out.dim_ = static_cast<int>(values.cols());
  out.times_ = times;
  out.table_ = values;
  return out;
}

Trajectory Trajectory::sampled(int dim) {
  if (dim < 0) throw std::invalid_argument("sampled trajectory: dim must be ≥ 0");
  Trajectory out;
  out.kind_ = Kind::kSampled;
  out.dim_ = dim;
  out.value_.setZero(dim);
  out.rate_.setZero(dim);
  out.acceleration_.setZero(dim);
  return out;
}

void Trajectory::set(const Eigen::Ref<const Eigen::VectorXd>& x,
                     const Eigen::Ref<const Eigen::VectorXd>& xd,
                     const Eigen::Ref<const Eigen::VectorXd>& xdd) {
  if (kind_ != Kind::kSampled)
    throw std::invalid_argument("only a sampled trajectory takes its value from outside");
  if (x.size() != dim_ || xd.size() != dim_ || xdd.size() != dim_)
    throw std::invalid_argument("sampled trajectory: x, ẋ and ẍ of " + std::to_string(dim_) +
                                " entries each");
  value_ = x;
  rate_ = xd;
  acceleration_ = xdd;
}

int Trajectory::piece(double t) const {
  const auto it = std::upper_bound(times_.begin(), times_.end(), t);
  return static_cast<int>(it - times_.begin()) - 1;
}

void Trajectory::sample(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> xd,
                        Eigen::Ref<Eigen::VectorXd> xdd) const {
  switch (kind_) {
    case Kind::kSampled:
      x = value_;
      xd = rate_;
      xdd = acceleration_;
      return;
    case Kind::kConstant:
      x = value_;
      xd.setZero();
      xdd.setZero();
      return;
    case Kind::kSinusoid: {
      if (t < t0_) {
        x.setZero();
        xd.setZero();
        xdd.setZero();
        return;
      }
      const double w = 2.0 * M_PI * frequency_;
      const double arg = w * (t - t0_) + phase_;
      x = amplitude_ * (std::sin(arg) - std::sin(phase_));
      xd = amplitude_ * (w * std::cos(arg));
      xdd = amplitude_ * (-w * w * std::sin(arg));
      return;
    }
    case Kind::kCubic: {
      xd.setZero();
      xdd.setZero();
      if (t <= times_.front()) {
        x = first_;
        return;
      }
      if (t >= times_.back()) {
        x = last_;
        return;
      }
      const int i = piece(t);
      const double s = t - times_[i];
      const auto c3 = table_.row(4 * i).transpose();
      const auto c2 = table_.row(4 * i + 1).transpose();
      const auto c1 = table_.row(4 * i + 2).transpose();
      const auto c0 = table_.row(4 * i + 3).transpose();
      x = ((c3 * s + c2) * s + c1) * s + c0;
      xd = (3.0 * c3 * s + 2.0 * c2) * s + c1;
      xdd = 6.0 * c3 * s + 2.0 * c2;
      return;
    }
    case Kind::kMinimumJerk:
    case Kind::kLinear: {
      xd.setZero();
      xdd.setZero();
      if (t <= times_.front()) {
        x = table_.row(0).transpose();
        return;
      }
      if (t >= times_.back()) {
        x = table_.row(table_.rows() - 1).transpose();
        return;
      }
      const int i = piece(t);
      const double duration = times_[i + 1] - times_[i];
      const double s = (t - times_[i]) / duration;
      const auto delta = (table_.row(i + 1) - table_.row(i)).transpose();
      if (kind_ == Kind::kLinear) {
        x = table_.row(i).transpose() + s * delta;
        xd = delta / duration;
        return;
      }
      const double p = s * s * s * (10 - 15 * s + 6 * s * s);
      const double dp = 30 * s * s * (1 - s) * (1 - s) / duration;
      const double ddp = 60 * s * (1 - s) * (1 - 2 * s) / (duration * duration);
      x = table_.row(i).transpose() + p * delta;
      xd = dp * delta;
      xdd = ddp * delta;
      return;
    }
  }
}

}  // namespace wbcbench
