// The generalised extreme-value (GEV) distribution of a per-fillet extreme, with what
// changes it as covariates: the number of pixels n it was taken over and their thickness t.
//   F(x) = exp(-c H(y)),  H(y) = (1 + xi y)^(-1/xi)  (xi = 0: exp(-y)),  y = (x - mu) / sigma
//   mu = m0 + m_logn (ln n - ln n_ref) + m_t (t - t_ref),  sigma = exp(s0 + s_t (t - t_ref))
//   c = exp(k_logn (ln n - ln n_ref)) = (n / n_ref)^k_logn
// The maximum of n pixels is max-stable in n: F_n = F_ref^(n / n_ref) for independent pixels
// (k_logn 1; texture correlated over a few pixels keeps the power with an exponent of its
// own), which moves both the location and, for a heavy tail, the scale. Thick meat is
// rougher. Fits since 2026-12-01 use k_logn with m_logn 0; models learned before carry
// m_logn with k_logn 0 and read as they did.
#pragma once
#include <cmath>

namespace rangex {

struct GevModel {
  double m0 = 0, m_logn = 0, m_t = 0;  // location
  double s0 = 0, s_t = 0;              // log scale
  double xi = 0;                       // shape: > 0 a heavy (Frechet) tail, < 0 a bounded one
  double log_n_ref = 0, t_ref = 0;     // the covariates' centres
  double k_logn = 0;                   // the intensity's power of n / n_ref (max-stability)

  double location(double n, double t) const { return location_ln(std::log(n), t); }
  double scale(double t) const;
  double log_c(double n) const { return log_c_ln(std::log(n)); }
  double cdf(double x, double n, double t) const { return cdf_ln(x, std::log(n), t); }
  // ln(1 - F(x)), accurate far into the tail (where 1 - F underflows F's rounding).
  double log_survival(double x, double n, double t) const {
    return log_survival_ln(x, std::log(n), t);
  }
  double quantile(double p, double n, double t) const;  // p in (0, 1)
  // -ln of the density at x; +inf outside the support.
  double neg_log_density(double x, double n, double t) const {
    return neg_log_density_ln(x, std::log(n), t);
  }

  // The same with ln n given: a fit evaluates each sample thousands of times, and its
  // logarithm was most of the time it took. The same values as the forms above.
  double location_ln(double ln_n, double t) const;
  double log_c_ln(double ln_n) const { return k_logn * (ln_n - log_n_ref); }
  double cdf_ln(double x, double ln_n, double t) const;
  double log_survival_ln(double x, double ln_n, double t) const;
  double neg_log_density_ln(double x, double ln_n, double t) const;
};

}  // namespace rangex
