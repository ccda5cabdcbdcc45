#include "core/gev_model.h"

#include <cmath>
#include <limits>

namespace rangex {

namespace {
constexpr double kGumbel = 1e-6;  // |xi| below this is the Gumbel limit
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

double GevModel::location_ln(double ln_n, double t) const {
  return m0 + m_logn * (ln_n - log_n_ref) + m_t * (t - t_ref);
}

double GevModel::scale(double t) const {
  return std::exp(s0 + s_t * (t - t_ref));
}

// The exceedance intensity -ln F = c (1 + xi y)^(-1/xi), or c exp(-y) for Gumbel.
static double intensity(const GevModel& g, double x, double ln_n, double t) {
  const double y = (x - g.location_ln(ln_n, t)) / g.scale(t), lc = g.log_c_ln(ln_n);
  if (std::abs(g.xi) < kGumbel) return std::exp(lc - y);
  const double a = 1 + g.xi * y;
  if (a <= 0) return g.xi > 0 ? kInf : 0.0;  // below the lower / above the upper end point
  return std::exp(lc - std::log(a) / g.xi);
}

double GevModel::cdf_ln(double x, double ln_n, double t) const {
  return std::exp(-intensity(*this, x, ln_n, t));
}

double GevModel::log_survival_ln(double x, double ln_n, double t) const {
  const double h = intensity(*this, x, ln_n, t);
  // 1 - exp(-h) = -expm1(-h): exact for the small h of a far tail.
  return h == kInf ? 0.0 : std::log(-std::expm1(-h));
}

double GevModel::quantile(double p, double n, double t) const {
  const double h = -std::log(p) * std::exp(-log_c(n));  // H at the quantile
  const double mu = location(n, t), s = scale(t);
  if (std::abs(xi) < kGumbel) return mu - s * std::log(h);
  return mu + s * (std::pow(h, -xi) - 1) / xi;
}

double GevModel::neg_log_density_ln(double x, double ln_n, double t) const {
  // -ln of c h(x) exp(-c H(x)), h = -dH/dx.
  const double s = scale(t), y = (x - location_ln(ln_n, t)) / s, lc = log_c_ln(ln_n);
  if (std::abs(xi) < kGumbel) return std::log(s) + y - lc + std::exp(lc - y);
  const double a = 1 + xi * y;
  if (a <= 0) return kInf;
  const double la = std::log(a);
  return std::log(s) + (1 + 1 / xi) * la - lc + std::exp(lc - la / xi);
}

}  // namespace rangex
