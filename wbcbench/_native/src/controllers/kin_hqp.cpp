#include "controllers/kin_hqp.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace wbcbench {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// _cap: scale r down so that ‖r‖ ≤ limit (the paper's bounded regulation, eq. 47)
template <typename D>
void cap(Eigen::MatrixBase<D>& r, double limit) {
  const double norm = r.norm();
  if (!(norm <= limit)) r *= limit / norm;
}

Eigen::Matrix3d skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d S;
  S << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return S;
}

}  // namespace

KinHqpTick::KinHqpTick(const std::string& model, const std::vector<std::string>& task_frames,
                       const std::vector<std::string>& contact_frames)
    : Tick(model, task_frames, contact_frames) {
  dyn_.set_inverse(false);  // the velocity level reads no M⁻¹
}

void KinHqpTick::configure(const KinHqpSettings& settings,
                           const std::vector<int>& kinematic_frames,
                           const std::vector<CapsuleSpec>& capsules,
                           const std::vector<std::pair<int, int>>& self_pairs,
                           const std::vector<BoxSpec>& boxes,
                           const std::vector<std::pair<int, int>>& obstacle_pairs) {
  const int nv = this->nv(), k = this->k();
  const int n_tasks = tasks_.size();
  const int n_frames = static_cast<int>(kinematic_frames.size());
  const int n_contacts = static_cast<int>(contact_frames_.size());
  const KinHqpSettings& s = settings;
  if (s.q_min.size() != k || s.q_max.size() != k || s.v_max.size() != k)
    throw std::invalid_argument("kin_hqp: joint limits need one entry per actuated joint");
  if (s.speed_limits.size() != n_tasks)
    throw std::invalid_argument("kin_hqp: speed_limits needs one entry per task");
  if (s.polygon_a.rows() != s.polygon_b.size() || (s.polygon_a.size() && s.polygon_a.cols() != 2))
    throw std::invalid_argument("kin_hqp: the support polygon needs (E, 2) normals, E offsets");
  if (s.support_foot && n_contacts == 0)
    throw std::invalid_argument("kin_hqp: base 'support_foot' needs at least one contact");
  if (s.gaze.on && (s.gaze.frame < 0 || s.gaze.frame >= n_frames || s.gaze.axis < 0 ||
                    s.gaze.axis > 2))
    throw std::invalid_argument("kin_hqp: gaze frame or axis out of range");
  for (const CapsuleSpec& c : capsules)
    if (c.frame < 0 || c.frame >= n_frames)
      throw std::invalid_argument("kin_hqp: capsule frame out of range");
  if (s.task_levels.size() != s.task_level_names.size())
    throw std::invalid_argument("kin_hqp: one name per task level");
  const int n_terms = n_tasks + (s.gaze.on ? 1 : 0);
  for (const auto& level : s.task_levels) {
    if (level.empty()) throw std::invalid_argument("kin_hqp: an empty task level");
    for (int i : level)
      if (i < 0 || i >= n_terms) throw std::invalid_argument("kin_hqp: task index out of range");
  }
  s_ = settings;
  dyn_.set_kinematic_frames(kinematic_frames);
  collisions_.configure(nv, capsules, self_pairs, boxes, obstacle_pairs);

  nx_ = s.support_foot ? k : nv;
  T_ = Matrix::Identity(nv, nx_);
  if (s.support_foot) T_.bottomRows(k).setIdentity();
  contacts_from_ = s.support_foot ? 1 : 0;
  contact_rows_ = 6 * (n_contacts - contacts_from_);
  const bool fixed = s.com == KinCom::kFixed;
  const int n_polygon =
      s.inequalities && s.com == KinCom::kPolygon ? static_cast<int>(s.polygon_b.size()) : 0;
  const int n_constraint_rows = s.inequalities ? k + n_polygon + collisions_.size() : 0;
  n_eq_ = contact_rows_ + (fixed ? 2 : 0);

  // the levels' shapes, as KinHqp.build lists them
  std::vector<int> task_rows_of;
  for (const auto& level : s.task_levels) {
    int rows = 0;
    for (int i : level) rows += i < n_tasks ? tasks_.dim(i) : 3;
    task_rows_of.push_back(rows);
  }
  contacts_level_ = contact_rows_ > 0 ? 0 : -1;
  constraints_level_ = (s.inequalities || fixed) ? contacts_level_ + 1 : -1;
  first_task_level_ = std::max(contacts_level_, constraints_level_) + 1;
  const int n_levels = first_task_level_ + static_cast<int>(s.task_levels.size());
  solver_.resize(std::max(n_levels, 1), nx_);
  auto shape = [&](int i, const std::string& name, int m, int mc, double damping) {
    HlsLevel& lv = solver_.level(i);
    lv.name = name;
    lv.has_task = m >= 0;
    lv.has_ineq = mc >= 0;
    lv.A.setZero(std::max(m, 0), nx_);
    lv.b.setZero(std::max(m, 0));
    lv.C.setZero(std::max(mc, 0), nx_);
    lv.l.setZero(std::max(mc, 0));
    lv.u.setZero(std::max(mc, 0));
    lv.damping = damping;
  };
  if (contacts_level_ >= 0) shape(contacts_level_, "contacts", contact_rows_, -1, 0.0);
  if (constraints_level_ >= 0)
    shape(constraints_level_, "constraints", fixed ? 2 : -1,
          s.inequalities ? n_constraint_rows : -1, 0.0);
  n_task_ = 0;
  for (size_t j = 0; j < s.task_levels.size(); ++j) {
    shape(first_task_level_ + static_cast<int>(j), s.task_level_names[j], task_rows_of[j], -1,
          s.damping);
    n_task_ += task_rows_of[j];
  }
  if (n_levels == 0) shape(0, "empty", 0, -1, 0.0);

  refs_.setZero(tasks_.rows() + (s.gaze.on ? 3 : 0));
  J_gaze_.setZero(3, nv);
  gaze_error_.setZero(3);
  gaze_angle_ = 0.0;
  Jcom_T_.setZero(2, nx_);
  polygon_com_.setZero(s.polygon_b.size());
  x0_.setZero(nx_);
  qd_.setZero(nv);
}

template <typename Src, typename Dst>
void KinHqpTick::times_root(const Src& src, Dst&& dst) const {
  if (s_.support_foot)
    dst.noalias() = src * T_;
  else
    dst = src;  // T = I: the product is the copy
}

void KinHqpTick::update_root_map() {
  // the support-foot elimination of the base: v_base = −B⁻¹ J_joints q̇_j, B the first
  // contact's LOCAL Jacobian's base columns
  if (!s_.support_foot) return;
  const auto Jc = dyn_.contact_jacobian().topRows<6>();
  base_lu_.compute(Jc.leftCols<6>());
  T_.topRows<6>() = base_lu_.solve(Jc.rightCols(k()));
  T_.topRows<6>() *= -1.0;
}

void KinHqpTick::task_rows(const Eigen::Ref<const Vector>& v) {
  for (int i = 0; i < tasks_.size(); ++i) {
    const int o = tasks_.offset(i), m = tasks_.dim(i);
    auto ref = refs_.segment(o, m);
    // ẋ_d from the term (error_vel = ẋ_d − J v), then ẋ_d + λ e
    ref.noalias() = tasks_.J().middleRows(o, m) * v;
    ref += tasks_.error_vel().segment(o, m);
    ref += tasks_.spec(i).kp.cwiseProduct(tasks_.error().segment(o, m));
    cap(ref, s_.speed_limits[i]);
  }
}

void KinHqpTick::gaze() {
  // f = v × p, ḟ = ([p]× [v]× J_ω − [v]× J_o) q̇ (eq. 54–55); v the frame's unit axis,
  // p = target − origin
  const KinGaze& g = s_.gaze;
  const Matrix& R = dyn_.kinematic_rotation(g.frame);
  const Eigen::Vector3d axis = R.col(g.axis);
  const Eigen::Vector3d p = g.target - Eigen::Vector3d(dyn_.kinematic_position(g.frame));
  const Matrix& J6 = dyn_.kinematic_jacobian(g.frame);
  const Eigen::Matrix3d vx = skew(axis), pvx = skew(p) * vx;
  J_gaze_.noalias() = pvx * J6.bottomRows<3>();
  J_gaze_.noalias() -= vx * J6.topRows<3>();
  const Eigen::Vector3d f = axis.cross(p);
  gaze_angle_ = std::atan2(f.norm(), axis.dot(p));
  gaze_error_ = -f;
  auto ref = refs_.tail<3>();
  ref = g.gain * gaze_error_;
  cap(ref, g.speed_limit);
}

bool KinHqpTick::run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                     double t) {
  times_.dynamics = dyn_.update(q, v);
  const auto t0 = Clock::now();
  const int k = this->k();
  tasks_.evaluate(dyn_, q, v, t);
  update_root_map();

  // 1. contacts: the sole velocities (LOCAL) are zero
  if (contacts_level_ >= 0)
    times_root(dyn_.contact_jacobian().middleRows(6 * contacts_from_, contact_rows_),
               solver_.level(contacts_level_).A);

  // 2. the inequalities (and the CoM hold, bounded by them)
  collisions_.evaluate(dyn_);
  n_ineq_ = 0;
  if (constraints_level_ >= 0) {
    HlsLevel& lv = solver_.level(constraints_level_);
    const Vector& com = dyn_.com();
    const bool com_rows = s_.com == KinCom::kFixed ||
                          (s_.inequalities && s_.com == KinCom::kPolygon && s_.polygon_b.size());
    if (com_rows) times_root(dyn_.J_com().topRows<2>(), Jcom_T_);
    if (s_.com == KinCom::kFixed) {
      lv.A = Jcom_T_;
      lv.b = -s_.com_gain * (com.head<2>() - s_.com0);
    }
    if (s_.inequalities) {
      const double xi = s_.joint_limit_gain;
      lv.C.topRows(k) = T_.bottomRows(k);
      for (int j = 0; j < k; ++j) {
        const double qj = q[7 + j];
        const double lower = std::max(xi * (s_.q_min[j] - qj), -s_.v_max[j]);
        const double upper = std::min(xi * (s_.q_max[j] - qj), s_.v_max[j]);
        // outside a limit, the limit's pull wins over the velocity bound
        lv.l[j] = std::min(lower, upper);
        lv.u[j] = upper;
      }
      int row = k;
      const int E = s_.com == KinCom::kPolygon ? static_cast<int>(s_.polygon_b.size()) : 0;
      if (E) {
        lv.C.middleRows(row, E).noalias() = s_.polygon_a * Jcom_T_;
        polygon_com_.noalias() = s_.polygon_a * com.head<2>();
        lv.u.segment(row, E) =
            s_.com_gain * (s_.polygon_b.array() - s_.com_margin - polygon_com_.array());
        lv.l.segment(row, E).setConstant(-kInf);
        row += E;
      }
      const int P = collisions_.size();
      if (P) {
        times_root(collisions_.grad(), lv.C.middleRows(row, P));
        lv.l.segment(row, P) =
            -s_.collision_gain * (collisions_.d().array() - s_.collision_margin);
        lv.u.segment(row, P).setConstant(kInf);
      }
      for (Eigen::Index r = 0; r < lv.l.size(); ++r)
        n_ineq_ += std::isfinite(lv.l[r]) + std::isfinite(lv.u[r]);
    }
  }

  // 3. the tasks, one level per priority
  task_rows(v);
  if (s_.gaze.on) gaze();
  const int n_tasks = tasks_.size();
  for (size_t j = 0; j < s_.task_levels.size(); ++j) {
    HlsLevel& lv = solver_.level(first_task_level_ + static_cast<int>(j));
    int row = 0;
    for (int i : s_.task_levels[j]) {
      if (i < n_tasks) {
        const int o = tasks_.offset(i), m = tasks_.dim(i);
        times_root(tasks_.J().middleRows(o, m), lv.A.middleRows(row, m));
        lv.b.segment(row, m) = refs_.segment(o, m);
        row += m;
      } else {
        times_root(J_gaze_, lv.A.middleRows(row, 3));
        lv.b.segment(row, 3) = refs_.tail<3>();
        row += 3;
      }
    }
  }
  times_.build = seconds_since(t0);

  const bool ok = solver_.solve(s_.algorithm, x0_, options_);
  solve_time_ = solver_.time();
  if (!ok) return false;
  if (s_.support_foot)
    qd_.noalias() = T_ * solver_.x();
  else
    qd_ = solver_.x();
  return true;
}

}  // namespace wbcbench
