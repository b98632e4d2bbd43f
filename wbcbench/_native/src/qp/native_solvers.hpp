// The level solves of a hierarchy tick that stay in C++: the handles (pool, handle) that have a
// QpSolver of their own, with a record of each solve for the tick's timer.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "qp/hierarchy.hpp"
#include "qp/solver.hpp"

namespace wbcbench {

class NativeSolvers {
 public:
  struct Record {
    int pool = 0, handle = 0;
    std::string level;
    QpOutcome outcome;
    std::shared_ptr<const QpBuffers> qp;     // a copy of the QP, when keeping them
    std::shared_ptr<const QpSolution> sol;   // and of its solution (x and the duals)
  };

  // solver for handle `handle` of pool `pool` (replacing any)
  void set(int pool, int handle, std::shared_ptr<QpSolver> solver);
  bool covers(int pool, int handle) const { return solvers_.count({pool, handle}) != 0; }
  // LevelSolver::solve for a covered handle: solve, record, hand back x and the duals of C
  bool solve(int pool, int handle, const std::string& level, const QpBuffers& qp, Vector& x,
             Vector& z, bool& has_z);
  // before a tick: forget the last tick's records
  void clear();
  const std::vector<Record>& records() const { return records_; }
  // the record of the last failed solve, or null
  const Record* failure() const { return failed_ < 0 ? nullptr : &records_[failed_]; }
  void reset();  // every solver's QpSolver::reset
  // keep a copy of every QP solved and of its solution in its record (solver dumps, the
  // independent check of what a backend reports; not for timing)
  void set_keep(bool keep) { keep_ = keep; }
  // seconds the last tick spent making those copies (taken out of the tick's timed region)
  double keep_seconds() const { return keep_seconds_; }

 private:
  std::map<std::pair<int, int>, std::shared_ptr<QpSolver>> solvers_;
  std::vector<Record> records_;
  int failed_ = -1;
  bool keep_ = false;
  double keep_seconds_ = 0.0;
};

}  // namespace wbcbench
