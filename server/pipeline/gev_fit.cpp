#include "pipeline/gev_fit.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "pipeline/nelder_mead.h"

namespace rangex {

namespace {

// The shape through a logistic map onto (xi_min, xi_max): no cliff at the bounds for the
// simplex to stall on.
double shape(double p, const GevFitOptions& o) {
  return o.xi_min + (o.xi_max - o.xi_min) / (1 + std::exp(-p));
}

GevModel from_params(const std::vector<double>& p, const GevModel& centre, const GevFitOptions& o) {
  GevModel g = centre;
  // The pixel count through max-stability (k_logn), not a free location slope: a heavy
  // tail's scale grows with n too (core/gev_model.h).
  g.m0 = p[0], g.m_logn = 0, g.k_logn = p[1], g.s0 = p[2], g.xi = shape(p[3], o);
  g.m_t = p[4], g.s_t = p[5];
  return g;
}

// Each sample's density over the window it could be seen in, F(upper) - F(lower); one
// below its window is left out. With a lower end the window is S(lower) - S(upper) from the
// survival's logarithm: where the model moves far below the samples both ends lie in its
// tail, and the difference of two CDFs next to 1 cancels to nothing.
double truncated_nll(const GevModel& g, const std::vector<ExtremeSample>& s,
                     const std::vector<double>& ln_n) {
  double sum = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    const ExtremeSample& e = s[i];
    if (e.x < e.lower) continue;
    if (e.x <= e.censor) {  // only that it lay in [lower, censor]
      const double lo = std::isfinite(e.lower) ? g.cdf_ln(e.lower, ln_n[i], e.t) : 0.0;
      sum -= std::log(std::max(1e-300, g.cdf_ln(e.censor, ln_n[i], e.t) - lo));
    } else
      sum += g.neg_log_density_ln(e.x, ln_n[i], e.t);
    if (std::isfinite(e.lower)) {
      const double lo = g.log_survival_ln(e.lower, ln_n[i], e.t);
      const double hi =
          std::isfinite(e.upper) ? g.log_survival_ln(e.upper, ln_n[i], e.t) : -HUGE_VAL;
      sum += hi < lo ? lo + std::log1p(-std::exp(hi - lo)) : std::log(1e-300);
    } else if (std::isfinite(e.upper)) {
      sum += std::log(std::max(1e-300, g.cdf_ln(e.upper, ln_n[i], e.t)));
    }
  }
  return sum;
}

// Each sample's ln n, once for every evaluation of a fit.
std::vector<double> log_pixels(const std::vector<ExtremeSample>& s) {
  std::vector<double> v(s.size());
  for (size_t i = 0; i < s.size(); ++i) v[i] = std::log(s[i].n);
  return v;
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
  // The shape starts a tenth into its range (near Gumbel for the default range).
  // k_logn starts at 1, independent pixels.
  const std::vector<double> x0 = {mean - 0.5772 * sigma, 1.0, std::log(sigma),
                                  std::log(0.1 / 0.9),   0.0, 0.0};
  const std::vector<double> step = {0.5 * sigma, 0.3, 0.3, 1.0, 0.02, 0.02};
  const std::vector<double> ln_n = log_pixels(s);
  auto objective = [&](const std::vector<double>& p) {
    return truncated_nll(from_params(p, centre, opt), s, ln_n);
  };
  const NelderMeadResult r = nelder_mead(objective, x0, step, 1e-8, 40000);
  GevFit f;
  f.model = from_params(r.x, centre, opt);
  f.converged = r.converged && std::isfinite(r.value);
  if (!(opt.tail_from > 0) || !f.converged) return f;
  // The tail: each extreme at or below the whole fit's `tail_from` quantile at its own
  // covariates counts only as lying there; the fit starts from the whole fit.
  std::vector<ExtremeSample> c = s;
  for (auto& e : c) e.censor = tail_level(f.model, opt.tail_from, e.n, e.t);
  auto tail = [&](const std::vector<double>& p) {
    return truncated_nll(from_params(p, centre, opt), c, ln_n);
  };
  const NelderMeadResult rt = nelder_mead(tail, r.x, step, 1e-8, 40000);
  if (!rt.converged || !std::isfinite(rt.value)) return f;
  f.whole = f.model, f.tail_from = opt.tail_from;
  f.model = from_params(rt.x, centre, opt);
  return f;
}

GevModel refit_drifted(const GevModel& model, const std::vector<ExtremeSample>& s,
                       double* location_shift, const GevFitOptions& opt) {
  if (location_shift) *location_shift = 0;
  if (s.size() < 10) return model;
  auto with = [&](const std::vector<double>& p) {
    GevModel g = model;
    g.m0 = p[0], g.s0 = p[1], g.xi = shape(p[2], opt);
    return g;
  };
  // The shape's start: the model's, inside the logistic's range.
  const double u = std::clamp((model.xi - opt.xi_min) / (opt.xi_max - opt.xi_min), 0.02, 0.98);
  const double shift = fit_location_shift(model, s);
  if (location_shift) *location_shift = shift;
  GevModel shifted = model;
  shifted.m0 += shift;
  const std::vector<double> ln_n = log_pixels(s);
  const NelderMeadResult r =
      nelder_mead([&](const std::vector<double>& p) { return truncated_nll(with(p), s, ln_n); },
                  {shifted.m0, model.s0, std::log(u / (1 - u))}, {0.3, 0.2, 1.0}, 1e-8, 6000);
  constexpr double kChi2_2dof_99 = 9.21;
  return 2 * (truncated_nll(shifted, s, ln_n) - r.value) > kChi2_2dof_99 ? with(r.x) : shifted;
}

double fit_location_shift(const GevModel& model, const std::vector<ExtremeSample>& s) {
  if (s.empty()) return 0;
  const std::vector<double> ln_n = log_pixels(s);
  auto at = [&](double d) {
    GevModel g = model;
    g.m0 += d;
    return truncated_nll(g, s, ln_n);
  };
  // A coarse scan over a generous bracket (in units of the model's scale), then a
  // golden-section search around its best: a likelihood truncated below is not unimodal (far
  // below the samples it flattens out again, every one of them in the tail).
  const double w = 10 * model.scale(model.t_ref), grid = w / 20;
  double best = 0, f_best = HUGE_VAL;
  for (int i = -20; i <= 20; ++i) {
    const double f = at(i * grid);
    if (f < f_best) best = i * grid, f_best = f;
  }
  double a = best - grid, b = best + grid;
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
