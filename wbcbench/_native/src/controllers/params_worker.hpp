// params: async — the operational-space parameters computed on a worker thread, as the papers'
// non-real-time thread does (TO-OSF §III-B2, OSF-HQP §III-B3). The control loop publishes its
// newest state every tick and takes the newest complete parameter set without waiting: the
// worker fills a set of its own, then swaps it into the shared slot (a pointer swap under a
// lock the loop only ever try-locks), so the loop never reads a torn set.
#pragma once

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "dynamics/osf.hpp"
#include "dynamics/state.hpp"
#include "tasks/tasks.hpp"

namespace wbcbench {

class ParamsWorker {
 public:
  // The worker's own dynamics (a second Pinocchio model and data, from the same serialised
  // model) holding the contacts `active` (indices into contact_frames, as
  // RobotDynamics::select_contacts takes them), a copy of the started tasks, and the
  // parameters' model: the parameters of one contact set.
  ParamsWorker(const std::string& model, const std::vector<std::string>& task_frames,
               const std::vector<std::string>& contact_frames,
               const std::vector<Matrix>& contact_points,
               const std::vector<Matrix>& contact_bases, const std::vector<int>& active,
               const TaskSet& tasks, const OsfModelSpec& spec);
  ~ParamsWorker();  // stops and joins the thread
  ParamsWorker(const ParamsWorker&) = delete;
  ParamsWorker& operator=(const ParamsWorker&) = delete;

  // the state of control tick `tick`, to compute the next set from
  void publish(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t,
               long tick);
  // Swaps the newest complete set into `current` when it is newer than `current`; false when
  // there is none or the worker is writing it right now. Throws when the worker stopped on an
  // error.
  bool take_newer(OsfParams& current);
  // sets computed so far
  long computed() const { return computed_.load(); }

 private:
  void run();

  RobotDynamics dyn_;
  TaskSet tasks_;
  OsfModel model_;
  // the published state (in_mutex_)
  std::mutex in_mutex_;
  std::condition_variable in_cv_;
  Vector q_in_, v_in_;
  double t_in_ = 0.0;
  long tick_in_ = -1;
  std::atomic<long> seq_in_{0};
  std::atomic<bool> stop_{false};
  // the worker blocks on in_cv_ only after polling for a while: waking a blocked thread costs
  // the loop a system call (tens of µs on a virtual machine), so the loop notifies only then
  std::atomic<bool> sleeping_{false};
  // the newest complete set (out_mutex_)
  std::mutex out_mutex_;
  OsfParams latest_;
  bool fresh_ = false;
  std::string error_;
  std::atomic<long> computed_{0};
  std::thread thread_;
};

}  // namespace wbcbench
