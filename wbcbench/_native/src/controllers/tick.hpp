// What every native controller tick shares: the per-tick dynamics, the tasks, the QP buffers a
// level is assembled into, and the stage timers.
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "dynamics/state.hpp"
#include "qp/buffers.hpp"
#include "tasks/tasks.hpp"

namespace wbcbench {

// Seconds per stage of the last tick, the names of the Python path's StageTimer.
struct StageTimes {
  double dynamics = 0.0, build = 0.0, params = 0.0;
};

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// That lw and uw have one entry per row of Cw (what Tick::set_wrench_bounds takes).
void check_wrench_bounds(const char* controller, const Matrix& Cw,
                         const Eigen::Ref<const Vector>& lw, const Eigen::Ref<const Vector>& uw);

// Tick::set_wrench_bounds's common part: checks lw and uw against the settings' wrench rows
// (s.Cw) and keeps them as s.lw, s.uw (the same sizes: no allocation).
template <class Settings>
void store_wrench_bounds(const char* controller, Settings& s, const Eigen::Ref<const Vector>& lw,
                         const Eigen::Ref<const Vector>& uw) {
  check_wrench_bounds(controller, s.Cw, lw, uw);
  s.lw = lw;
  s.uw = uw;
}

// The robot's dynamics and tasks of one controller.
class Tick {
 public:
  Tick(const std::string& model, const std::vector<std::string>& task_frames,
       const std::vector<std::string>& contact_frames);
  virtual ~Tick() = default;

  RobotDynamics& dynamics() { return dyn_; }
  TaskSet& tasks() { return tasks_; }
  const StageTimes& times() const { return times_; }
  int nv() const { return dyn_.nv(); }
  int k() const { return dyn_.nv() - 6; }
  // contacts made of points (RobotDynamics::set_contact_points); before configure()
  void set_contact_points(const std::vector<Matrix>& points, const std::vector<Matrix>& bases) {
    dyn_.set_contact_points(points, bases);
  }

  // -- a contact set that changes (the mirror of Controller.select_contacts)
  // The contacts the tick holds: increasing indices into the contact frames (every contact
  // until called). A change re-sizes the dynamics' contact buffers; the controller's QPs follow
  // when its settings for the new set (wrench inequalities, tasks) are handed over again
  // (configure), which sizes them. The same set again does nothing and allocates nothing.
  // Returns whether the set changed. Each set held is numbered, in the order first held (0:
  // every contact, as made): contact_set() is the current one's number.
  virtual bool select_contacts(const std::vector<int>& active);
  // select_contacts of the set held before under number `set`, without crossing a list: what a
  // change of contacts calls once every set of the schedule has been held (and configured)
  bool switch_contacts(int set);
  int contact_set() const { return set_; }
  int contact_sets() const { return static_cast<int>(sets_.size()); }
  // This tick's bounds lw ≤ Cw f ≤ uw on the active contacts' wrench rows (the normal-force
  // bounds of a contact that unloads or has just landed), (nw,) each as the configured Cw's
  // rows; copied into the QPs without allocating. A tick that does not follow a contact
  // schedule refuses.
  virtual void set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                 const Eigen::Ref<const Vector>& uw);

 protected:
  // dynamics and tasks at (q, v, t); times the dynamics stage
  void evaluate(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t);

  // what the dynamics were made from (a worker thread makes its own from them)
  std::string model_text_;
  std::vector<std::string> task_frames_, contact_frames_;
  RobotDynamics dyn_;
  TaskSet tasks_;
  StageTimes times_;
  // the contact sets held so far, numbered in order, and the current one's number
  std::vector<std::vector<int>> sets_;
  int set_ = 0;
  // after the set changed to number `set` (set_ already holds it): a controller that keeps a
  // workspace per contact set switches to that set's
  virtual void contacts_switched(int set) {}
};

}  // namespace wbcbench
