#include "qp/buffers.hpp"

#include <limits>

namespace wbcbench {

void QpBuffers::resize(int n, int n_eq, int n_in, bool box) {
  H.setZero(n, n);
  g.setZero(n);
  A.setZero(n_eq, n);
  b.setZero(n_eq);
  C.setZero(n_in, n);
  l.setZero(n_in);
  u.setZero(n_in);
  has_box = box;
  lb.setConstant(box ? n : 0, -std::numeric_limits<double>::infinity());
  ub.setConstant(box ? n : 0, std::numeric_limits<double>::infinity());
}

bool QpBuffers::reshapes(int n, int n_eq, int n_in, bool box) const {
  return H.rows() != n || A.rows() != n_eq || C.rows() != n_in || has_box != box;
}

bool QpBuffers::finite() const {
  const auto no_nan = [](const Vector& x) { return !x.hasNaN(); };
  return H.allFinite() && g.allFinite() && A.allFinite() && b.allFinite() && C.allFinite() &&
         no_nan(l) && no_nan(u) && no_nan(lb) && no_nan(ub);
}

}  // namespace wbcbench
