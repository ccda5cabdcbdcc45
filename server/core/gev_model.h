// The generalised extreme-value (GEV) distribution of a per-fillet extreme, with what
// changes it as covariates: the number of pixels n it was taken over and their thickness t.
//   F(x) = exp(-(1 + xi y)^(-1/xi)),  y = (x - mu) / sigma   (xi = 0: exp(-exp(-y)))
//   mu = m0 + m_logn (ln n - ln n_ref) + m_t (t - t_ref),  sigma = exp(s0 + s_t (t - t_ref))
// The maximum of n weakly dependent pixels moves with ln n, and thick meat is rougher.
#pragma once

namespace rangex {

struct GevModel {
  double m0 = 0, m_logn = 0, m_t = 0;  // location
  double s0 = 0, s_t = 0;              // log scale
  double xi = 0;                       // shape: > 0 a heavy (Frechet) tail, < 0 a bounded one
  double log_n_ref = 0, t_ref = 0;     // the covariates' centres

  double location(double n, double t) const;
  double scale(double t) const;
  double cdf(double x, double n, double t) const;
  // ln(1 - F(x)), accurate far into the tail (where 1 - F underflows F's rounding).
  double log_survival(double x, double n, double t) const;
  double quantile(double p, double n, double t) const;  // p in (0, 1)
  // -ln of the density at x; +inf outside the support.
  double neg_log_density(double x, double n, double t) const;
};

}  // namespace rangex
