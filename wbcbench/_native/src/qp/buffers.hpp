// One QP in the form of wbcbench.qp.Problem, in buffers the native side owns and the Python
// solvers read as NumPy views (no copy).
#pragma once

#include <Eigen/Core>

#include "types.hpp"

namespace wbcbench {

//   minimise ½ xᵀ H x + gᵀ x  s.t.  A x = b,  l ≤ C x ≤ u,  lb ≤ x ≤ ub.
// Row-major, so that the NumPy views the solvers read are C-contiguous.
struct QpBuffers {
  RowMatrix H, A, C;
  Vector g, b, l, u, lb, ub;
  bool has_box = false;

  // sizes every buffer and zeroes it (bounds ±inf); memory is kept when the sizes are unchanged
  void resize(int n, int n_eq, int n_in, bool box);
  // true when resize() would change a size (the NumPy views of the buffers must be re-made)
  bool reshapes(int n, int n_eq, int n_in, bool box) const;
  // every entry finite except ±inf bounds (a NaN anywhere is a failed tick, not a solve)
  bool finite() const;
};

}  // namespace wbcbench
