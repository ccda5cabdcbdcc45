#include "pipeline/gev_fit.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/normal_quantile.h"
#include "pipeline/nelder_mead.h"

namespace rangex {

namespace {

// The shape through a logistic map onto (xi_min, xi_max): no cliff at the bounds for the
// simplex to stall on.
double shape(double p, const GevFitOptions& o) {
  return o.xi_min + (o.xi_max - o.xi_min) / (1 + std::exp(-p));
}

// The inverse: the free parameter of shape xi (clamped inside the range).
double shape_param(double xi, const GevFitOptions& o) {
  const double u = std::clamp((xi - o.xi_min) / (o.xi_max - o.xi_min), 1e-6, 1 - 1e-6);
  return std::log(u / (1 - u));
}

GevModel from_params(const std::vector<double>& p, const GevModel& centre, const GevFitOptions& o) {
  GevModel g = centre;
  g.m0 = p[0], g.m_logn = p[1], g.s0 = p[2], g.xi = shape(p[3], o);
  g.m_t = p[4], g.s_t = p[5];
  return g;
}

double nll(const GevModel& g, const std::vector<ExtremeSample>& s) {
  double sum = 0;
  for (const ExtremeSample& e : s) sum += g.neg_log_density(e.x, e.n, e.t);
  return sum;
}

double truncated_nll(const GevModel& g, const std::vector<ExtremeSample>& s) {
  double sum = nll(g, s);
  for (const ExtremeSample& e : s)
    if (std::isfinite(e.upper)) sum += std::log(std::max(1e-300, g.cdf(e.upper, e.n, e.t)));
  return sum;
}

}  // namespace

GevFit fit_gev(const std::vector<ExtremeSample>& s, const GevFitOptions& opt) {
  if (s.size() < 10)
    fail("an extreme-value fit needs at least 10 fillet extremes (got ", s.size(), ")");
  GevModel centre;
  double mean = 0, var = 0, ln = 0, t = 0;
  for (const auto& e : s) mean += e.x, ln += std::log(e.n), t += e.t;
  mean /= double(s.size()), centre.log_n_ref = ln / double(s.size()),
                            centre.t_ref = t / double(s.size());
  for (const auto& e : s) var += (e.x - mean) * (e.x - mean);
  var /= double(s.size() - 1);
  // Gumbel moments as the start.
  const double sigma = std::max(1e-3, std::sqrt(6 * var) / M_PI);
  // The shape starts at Gumbel, or a tenth into its range where that excludes Gumbel's
  // neighbourhood (the logistic is flat at its ends: the simplex would stall there).
  const double u0 = std::clamp(-opt.xi_min / (opt.xi_max - opt.xi_min), 0.1, 0.9);
  const std::vector<double> x0 = {mean - 0.5772 * sigma,   0.0, std::log(sigma),
                                  std::log(u0 / (1 - u0)), 0.0, 0.0};
  const std::vector<double> step = {0.5 * sigma, 0.2 * sigma, 0.3, 1.0, 0.02, 0.02};
  auto objective = [&](const std::vector<double>& p) {
    return truncated_nll(from_params(p, centre, opt), s);
  };
  const NelderMeadResult r = nelder_mead(objective, x0, step, 1e-8, 40000);
  GevFit f;
  f.model = from_params(r.x, centre, opt);
  f.converged = r.converged && std::isfinite(r.value);
  return f;
}

double profile_upper_level(const std::vector<ExtremeSample>& s, const GevFit& fit, double q,
                           double n, double t, double confidence, const GevFitOptions& opt) {
  const GevModel& m = fit.model;
  const double h = -std::log1p(-q);  // the intensity at the quantile 1 - q
  const double dn = std::log(n) - m.log_n_ref, dt = t - m.t_ref;
  // The model whose quantile at (n, t) is z: the location's intercept follows the rest.
  auto at = [&](double z, const std::vector<double>& p) {
    GevModel g = m;
    g.m_logn = p[0], g.s0 = p[1], g.xi = shape(p[2], opt), g.m_t = p[3], g.s_t = p[4];
    const double y = std::abs(g.xi) < 1e-6 ? -std::log(h) : (std::pow(h, -g.xi) - 1) / g.xi;
    g.m0 = z - g.m_logn * dn - g.m_t * dt - g.scale(t) * y;
    return g;
  };
  std::vector<double> best = {m.m_logn, m.s0, shape_param(m.xi, opt), m.m_t, m.s_t};
  const double z_hat = m.quantile(1 - q, n, t);
  auto profile = [&](double z) {
    const NelderMeadResult r = nelder_mead(
        [&](const std::vector<double>& p) {
          const double v = truncated_nll(at(z, p), s);
          return std::isfinite(v) ? v : 1e300;  // outside the support
        },
        best, {0.05, 0.1, 0.5, 0.01, 0.01}, 1e-9, 3000);
    if (r.value < 1e299) best = r.x;  // the next level starts from this one's best model
    return r.value;
  };
  const double peak = std::min(truncated_nll(m, s), profile(z_hat));
  // 2 (nll - peak) against chi2_1(2 confidence - 1) = zq^2; its root grows about linearly
  // in z: bracket its crossing of zq, then regula falsi (Illinois) on it.
  const double zq = normal_quantile(confidence);
  auto g = [&](double z) { return std::sqrt(2 * std::max(0.0, profile(z) - peak)) - zq; };
  double lo = z_hat, g_lo = -zq, step = m.scale(t), hi = z_hat + step, g_hi = g(hi);
  for (int k = 0; g_hi < 0; ++k) {
    if (k == 20) return HUGE_VAL;
    lo = hi, g_lo = g_hi, step *= 2, hi = z_hat + step, g_hi = g(hi);
  }
  int side = 0;
  for (int k = 0; k < 40 && hi - lo > 1e-4 * m.scale(t); ++k) {
    const double z = hi - g_hi * (hi - lo) / (g_hi - g_lo), gz = g(z);
    if (gz < 0) {
      lo = z, g_lo = gz;
      if (side == -1) g_hi *= 0.5;
      side = -1;
    } else {
      hi = z, g_hi = gz;
      if (side == 1) g_lo *= 0.5;
      side = 1;
    }
  }
  return hi;
}

GevModel refit_drifted(const GevModel& model, const std::vector<ExtremeSample>& s,
                       const GevFitOptions& opt) {
  if (s.size() < 10) return model;
  auto with = [&](const std::vector<double>& p) {
    GevModel g = model;
    g.m0 = p[0], g.s0 = p[1], g.xi = shape(p[2], opt);
    return g;
  };
  // The shape's start: the model's, inside the logistic's range.
  const double u = std::clamp((model.xi - opt.xi_min) / (opt.xi_max - opt.xi_min), 0.02, 0.98);
  GevModel shifted = model;
  shifted.m0 += fit_location_shift(model, s);
  const NelderMeadResult r =
      nelder_mead([&](const std::vector<double>& p) { return truncated_nll(with(p), s); },
                  {shifted.m0, model.s0, std::log(u / (1 - u))}, {0.3, 0.2, 1.0}, 1e-8, 6000);
  constexpr double kChi2_2dof_99 = 9.21;
  return 2 * (truncated_nll(shifted, s) - r.value) > kChi2_2dof_99 ? with(r.x) : shifted;
}

double fit_location_shift(const GevModel& model, const std::vector<ExtremeSample>& s) {
  if (s.empty()) return 0;
  auto at = [&](double d) {
    GevModel g = model;
    g.m0 += d;
    return truncated_nll(g, s);
  };
  // Golden-section search over a generous bracket (in units of the model's scale).
  const double w = 10 * model.scale(model.t_ref);
  double a = -w, b = w;
  const double k = 0.5 * (std::sqrt(5.0) - 1);
  double c = b - k * (b - a), d = a + k * (b - a), fc = at(c), fd = at(d);
  for (int i = 0; i < 80; ++i) {
    if (fc < fd)
      b = d, d = c, fd = fc, c = b - k * (b - a), fc = at(c);
    else
      a = c, c = d, fc = fd, d = a + k * (b - a), fd = at(d);
  }
  return 0.5 * (a + b);
}

}  // namespace rangex
