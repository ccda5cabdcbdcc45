#include "calib/block_covariance.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>

namespace rangex {

std::vector<double> block_stddev(ceres::Problem& problem, const double* block, int n,
                                 double residual_variance) {
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  ceres::Covariance cov(co);
  const std::vector<std::pair<const double*, const double*>> blocks = {{block, block}};
  std::vector<double> C(size_t(n) * n);
  if (!cov.Compute(blocks, &problem) || !cov.GetCovarianceBlock(block, block, C.data())) return {};
  std::vector<double> sd(n);
  for (int i = 0; i < n; ++i)
    sd[i] = std::sqrt(std::max(0.0, C[size_t(i) * n + i] * residual_variance));
  return sd;
}

}  // namespace rangex
