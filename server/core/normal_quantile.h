// The standard normal distribution's quantile, by bisection on erfc: exact to rounding, and
// cheap where it is needed (a confidence level turned into a bound, once per fit).
#pragma once
#include <cmath>

namespace rangex {

inline double normal_quantile(double p) {
  double lo = -40, hi = 40;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace rangex
