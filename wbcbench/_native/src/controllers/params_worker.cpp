#include "controllers/params_worker.hpp"

#include <chrono>
#include <exception>
#include <stdexcept>
#include <utility>

namespace wbcbench {

namespace {
constexpr std::chrono::microseconds kPoll{2000};
}  // namespace

ParamsWorker::ParamsWorker(const std::string& model, const std::vector<std::string>& task_frames,
                           const std::vector<std::string>& contact_frames,
                           const std::vector<Matrix>& contact_points,
                           const std::vector<Matrix>& contact_bases,
                           const std::vector<int>& active, const TaskSet& tasks,
                           const OsfModelSpec& spec)
    : dyn_(model, task_frames, contact_frames), tasks_(tasks), model_(spec) {
  dyn_.set_inverse(true);
  dyn_.set_contact_points(contact_points, contact_bases);
  if (active != dyn_.active_contacts()) dyn_.select_contacts(active);
  thread_ = std::thread([this] { run(); });
}

ParamsWorker::~ParamsWorker() {
  {
    std::lock_guard<std::mutex> lock(in_mutex_);
    stop_ = true;
  }
  in_cv_.notify_one();
  if (thread_.joinable()) thread_.join();
}

void ParamsWorker::publish(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v,
                           double t, long tick) {
  {
    std::lock_guard<std::mutex> lock(in_mutex_);
    q_in_ = q;
    v_in_ = v;
    t_in_ = t;
    tick_in_ = tick;
    ++seq_in_;
  }
  if (sleeping_.load()) in_cv_.notify_one();
}

bool ParamsWorker::take_newer(OsfParams& current) {
  std::unique_lock<std::mutex> lock(out_mutex_, std::try_to_lock);
  if (!lock.owns_lock()) return false;
  if (!error_.empty()) throw std::runtime_error("the parameter worker stopped: " + error_);
  if (!fresh_ || latest_.tick <= current.tick) return false;
  std::swap(current, latest_);  // O(1): the matrices swap their buffers
  fresh_ = false;
  return true;
}

void ParamsWorker::run() {
  OsfParams work;
  Vector q, v;
  long seen = 0;
  try {
    for (;;) {
      double t;
      long tick;
      // poll for up to a control period's worth, then block until the loop publishes
      const auto until = std::chrono::steady_clock::now() + kPoll;
      while (seq_in_.load() == seen && !stop_ && std::chrono::steady_clock::now() < until)
        std::this_thread::yield();
      {
        std::unique_lock<std::mutex> lock(in_mutex_);
        sleeping_ = true;
        in_cv_.wait(lock, [&] { return stop_ || seq_in_.load() != seen; });
        sleeping_ = false;
        if (stop_) return;
        seen = seq_in_;
        q = q_in_;
        v = v_in_;
        t = t_in_;
        tick = tick_in_;
      }
      dyn_.update(q, v);
      tasks_.evaluate(dyn_, q, v, t);
      model_.compute(dyn_, tasks_.J(), tasks_.drift(), tick, work);
      std::lock_guard<std::mutex> lock(out_mutex_);
      std::swap(latest_, work);
      fresh_ = true;
      ++computed_;
    }
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(out_mutex_);
    error_ = e.what();
  }
}

}  // namespace wbcbench
