// The matrix and vector types every part of the native tick shares.
#pragma once

#include <Eigen/Core>

namespace wbcbench {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Matrix = Eigen::MatrixXd;
using Vector = Eigen::VectorXd;

}  // namespace wbcbench
