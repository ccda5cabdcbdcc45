#include "pipeline/binomial_tail.h"

#include <algorithm>
#include <cmath>

namespace rangex {

double binomial_at_most(int k, int n, double p) {
  if (k < 0) return 0;
  if (k >= n) return 1;
  if (p <= 0) return 1;
  if (p >= 1) return 0;
  // Terms summed in log space: at n of a few hundred and p near 1 the plain powers underflow.
  const double lp = std::log(p), lq = std::log1p(-p);
  double sum = 0;
  for (int i = 0; i <= k; ++i)
    sum += std::exp(std::lgamma(n + 1.0) - std::lgamma(i + 1.0) - std::lgamma(n - i + 1.0) +
                    i * lp + (n - i) * lq);
  return std::min(1.0, sum);
}

}  // namespace rangex
