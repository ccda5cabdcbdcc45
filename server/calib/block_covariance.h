// Standard deviations of one parameter block after a least-squares solve: Ceres'
// (J^T J)^-1 (by SVD, so a rank-deficient fit gives pseudo-inverse values, not a failure)
// scaled by the residual variance, since Ceres takes residuals to have unit variance.
#pragma once
#include <vector>

namespace ceres {
class Problem;
}

namespace rangex {

// sd[i] for the n parameters of `block`; empty when the covariance cannot be computed.
std::vector<double> block_stddev(ceres::Problem& problem, const double* block, int n,
                                 double residual_variance);

}  // namespace rangex
