// Hierarchical least squares with regularised QR in reduced coordinates: the native mirror of
// wbcbench/qp/hls.py (the RQR-HQP paper's method, §II–III), and of the two baselines of
// wbcbench/qp/hls_baselines.py (the SVD task-priority algorithm and the full-coordinate QR).
//
// Same steps, tolerances and per-level statistics as the Python reference, so the two agree to
// round-off: column-pivoted Householder QR kept in compact form (LAPACK dgeqp3's unblocked
// algorithm, dlaqp2, with its column-norm downdating), its orthogonal factor applied and never
// formed, Tikhonov damping through the QR of the small augmented factor with the basis for the
// next level taken from the non-regularised factorisation, a primal active set per level whose
// saturated rows are carried down as equalities, and the least-violation phase.
//
// Every buffer grows to the largest stack seen and is then reused: once a stack of given sizes
// has been solved, solving it again allocates nothing (the SVD baseline's Eigen solvers
// included, one per level).
#pragma once

#include <Eigen/Core>
#include <Eigen/Householder>
#include <Eigen/SVD>
#include <string>
#include <vector>

#include "types.hpp"

namespace wbcbench {

// A grow-only matrix: views of the size asked for over storage kept across calls.
class HlsBuffer {
 public:
  Eigen::Block<Matrix> view(Eigen::Index rows, Eigen::Index cols);

 private:
  Matrix m_;
};

// A grow-only vector.
Eigen::VectorBlock<Vector> head_of(Vector& v, Eigen::Index n);

// M[:, piv] = Q R of a (q, m) matrix, Q held as Householder reflectors: the mirror of
// PivotedQR / pivoted_qr in wbcbench/qp/hls.py (LAPACK dgeqp3 there).
class PivotedQr {
 public:
  // Storage of the (q, m) matrix to factorise; the caller fills it, then calls factor().
  Eigen::Block<Matrix> load(Eigen::Index q, Eigen::Index m);
  // Factorises the loaded matrix; rank = #{|R_ii| > rank_tol}.
  void factor(double rank_tol);
  Eigen::Index rows() const { return q_; }
  Eigen::Index cols() const { return m_; }
  Eigen::Index size() const { return k_; }  // reflectors: min(q, m)
  Eigen::Index rank() const { return rank_; }
  int piv(Eigen::Index i) const { return piv_[i]; }
  Eigen::Block<const Matrix> h() const { return h_.topLeftCorner(q_, m_); }

  // c ← Q c, or Qᵀ c with trans; c is (q, ·).
  template <typename D>
  void apply_left(const Eigen::MatrixBase<D>& c_, bool trans) {
    auto& c = const_cast<Eigen::MatrixBase<D>&>(c_);
    if (k_ == 0 || c.size() == 0) return;
    if (work_.size() < c.cols()) work_.resize(c.cols());
    const auto H = h();
    for (Eigen::Index j = 0; j < k_; ++j) {
      const Eigen::Index i = trans ? j : k_ - 1 - j;
      c.bottomRows(q_ - i).applyHouseholderOnTheLeft(H.col(i).tail(q_ - i - 1), tau_[i],
                                                     work_.data());
    }
  }
  // c ← c Q; c is (·, q).
  template <typename D>
  void apply_right(const Eigen::MatrixBase<D>& c_) {
    auto& c = const_cast<Eigen::MatrixBase<D>&>(c_);
    if (k_ == 0 || c.size() == 0) return;
    if (work_.size() < c.rows()) work_.resize(c.rows());
    const auto H = h();
    for (Eigen::Index i = 0; i < k_; ++i)
      c.rightCols(q_ - i).applyHouseholderOnTheRight(H.col(i).tail(q_ - i - 1), tau_[i],
                                                     work_.data());
  }

 private:
  Matrix h_;
  Vector tau_, vn1_, vn2_, work_;
  Eigen::VectorXi piv_;
  Eigen::Index q_ = 0, m_ = 0, k_ = 0, rank_ = 0;
};

// One priority level (wbcbench.qp.hls.Level): A x = b in the least-squares sense, subject to
// l ≤ C x ≤ u; either part may be absent (has_task, has_ineq false).
struct HlsLevel {
  std::string name;
  Matrix A, C;  // (m, n), (mc, n)
  Vector b, l, u;
  double damping = 0.0;  // Tikhonov factor k
  bool has_task = false;
  bool has_ineq = false;
};

// What one level did (wbcbench.qp.hls.LevelStats).
struct HlsLevelStats {
  double time = 0.0;  // [s]
  int iterations = 0;
  int n_active = 0;
  int n_saturated = 0;
  double residual = 0.0;
  double violation = 0.0;
  int rank = 0;
  int dof_left = 0;
  Vector x;  // (n,) after the level
};

struct HlsOptions {
  double rank_tol = 1e-9;
  double feas_tol = 1e-9;
  int max_iter = 0;  // per active set; 0: 10 (q + rows) + 10
};

// solve_hls, solve_fullqr_hierarchy, solve_svd_hierarchy
enum class HlsAlgorithm { kReducedQr, kFullQr, kSvd };

// A stack of levels and the three algorithms that solve it (wbcbench.qp.hls.HlsResult is the
// result: x, stats(), time; ok false with message() where the reference raises SolverError).
class HlsSolver {
 public:
  // n_levels levels of n variables (keeps the levels' storage)
  void resize(int n_levels, int n);
  int n_levels() const { return static_cast<int>(levels_.size()); }
  int n() const { return n_; }
  HlsLevel& level(int i) { return levels_.at(i); }
  // Solves the stack from x0 (n,) with the levels' own dampings; returns ok.
  bool solve(HlsAlgorithm algorithm, const Eigen::Ref<const Vector>& x0,
             const HlsOptions& options);

  const Vector& x() const { return x_; }
  const std::vector<HlsLevelStats>& stats() const { return stats_; }  // one per level solved
  double time() const { return time_; }                              // [s]
  bool ok() const { return message_.empty(); }
  const std::string& message() const { return message_; }

 private:
  bool reduced_qr(const HlsOptions& o);
  bool full_qr(const HlsOptions& o);
  bool svd(const HlsOptions& o);
  bool equality_level(const HlsLevel& lv, double rank_tol, int& rank);
  bool inequality_level(const HlsLevel& lv, const HlsOptions& o, HlsLevelStats& st);
  bool least_violation(const HlsLevel& lv, const HlsOptions& o, int& iterations);
  bool active_set(Eigen::Index m, Eigen::Index q, Eigen::Index mi, double k, const HlsOptions& o,
                  int& iterations);
  void face_basis(Eigen::Index q, Eigen::Index mi, double rank_tol);
  bool multipliers(Eigen::Index q);
  bool ls_coefficients(const PivotedQr& fac, const Eigen::Ref<const Vector>& r, double k,
                       Eigen::Index& size);
  bool lstsq_qr(Eigen::Index rows, Eigen::Index cols, Eigen::Index size);
  void null_basis(PivotedQr& fac);
  bool fail(const std::string& message);
  HlsLevelStats& next_stats(std::size_t i);
  double residual(const HlsLevel& lv);

  std::vector<HlsLevel> levels_;
  int n_ = 0;
  std::vector<HlsLevelStats> stats_;
  double time_ = 0.0;
  std::string message_;

  // the hierarchy: x, the basis Z = Zb[:, z0 : z0 + p] of what the levels above left free, and
  // the inequalities G x ≤ h (rows [0, mi)) still free
  Vector x_;
  Matrix Zb_;
  Eigen::Index z0_ = 0, p_ = 0, mi_ = 0;
  HlsBuffer G_;
  Vector h_;

  // the active set's problem, min ½‖F z − g‖² + ½k²‖z‖² s.t. P z ≤ hp, its face basis N and
  // its solution z, working set and multipliers
  HlsBuffer F_, P_, N_;
  Eigen::Index ndim_ = 0;
  Vector g_, hp_, z_, lam_, step_, shift_, rhs_, v_, grad_, Pp_, Pz_, rowsum_;
  std::vector<int> working_, saturated_;
  std::vector<char> in_working_;
  PivotedQr face_, ls_, basis_;
  HlsBuffer aux_;  // the small least-squares problem of ls_coefficients
  Vector w_, auxr_, work_;

  // level scratch
  Vector r_, Cx_, lo_, hi_;
  std::vector<int> kept_;

  // baselines: projector / basis, stacked tasks, SVD per level
  HlsBuffer proj_, basis_cols_, stacked_;
  std::vector<Matrix> svd_in_;
  std::vector<Eigen::JacobiSVD<Matrix>> svd_;
};

}  // namespace wbcbench
