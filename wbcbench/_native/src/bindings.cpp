// The module: each part of the native tick binds itself in src/bind/ (conversion and
// ownership only, no mathematics there).
#include "bind/bind.hpp"

NB_MODULE(_core, m) {
  m.doc() = "wbcbench's native real-time tick (C++17, Eigen, Pinocchio)";
  m.attr("compiler") = WBCBENCH_COMPILER;
  m.attr("cxx_flags") = WBCBENCH_CXX_FLAGS;
  wbcbench::bind_dynamics(m);
  wbcbench::bind_reduced(m);
  wbcbench::bind_controllers(m);
  wbcbench::bind_osf(m);
  wbcbench::bind_solvers(m);
  wbcbench::bind_hierarchy(m);
  wbcbench::bind_rc_lqp(m);
  wbcbench::bind_hls(m);
  wbcbench::bind_kin_hqp(m);
}
