#include "backends/robust_fit_batch.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace rangex {

namespace {

struct State {
  bool active = false;
  double b0 = 0, b1 = 0, scale = 0, dev_prev = 0;
  double prev[3] = {0, 0, 0};                // the line before this iteration's
  double before[3] = {0, 0, 0};              // and the one before that
  double t_lo = HUGE_VAL, t_hi = -HUGE_VAL;  // the used pixels' thickness range
  std::vector<double> w;                     // the weights of the last fit, per used pixel
};

// The weighted line from one fillet's sums (raw moments; centred here).
bool line_from(const double* s, double& b0, double& b1) {
  const double sw = s[0];
  if (!(sw > 0)) return false;
  const double mx = s[1] / sw, my = s[2] / sw;
  const double sxx = s[3] - sw * mx * mx, sxy = s[4] - sw * mx * my;
  if (!(sxx > 1e-12 * sw * std::max(1.0, mx * mx))) return false;
  b1 = sxy / sxx;
  b0 = my - b1 * mx;
  return true;
}

double mad_scale(const double* r, const uint8_t* use, int from, int to, std::vector<double>& tmp) {
  tmp.clear();
  for (int i = from; i < to; ++i)
    if (use[i]) tmp.push_back(std::abs(r[i]));
  return median_inplace(tmp.data(), tmp.size()) / kMadNormal;
}

// statsmodels' deviance (robust_fit.cpp): sum rho(r / s_w) with s_w = sum(w r^2) / (n - 2).
double deviance(const double* r, const uint8_t* use, int from, int to, const std::vector<double>* w,
                double c) {
  double ss = 0;
  size_t k = 0, n = 0;
  for (int i = from; i < to; ++i)
    if (use[i]) {
      ss += (w ? (*w)[k++] : 1.0) * r[i] * r[i];
      ++n;
    }
  const double sw = ss / double(n - 2);
  double d = 0, carry = 0;
  for (int i = from; i < to; ++i) {
    if (!use[i]) continue;
    const double z = r[i] / sw / c;
    if (std::abs(z) > 1) continue;
    const double u = 1 - z * z;
    const double term = -u * u * u * c * c / 6 - carry;
    const double t = d + term;
    carry = (t - d) - term;
    d = t;
  }
  return d;
}

}  // namespace

std::vector<BatchFit> fit_tukey_lines(Backend& backend, const FilletBatch& batch,
                                      const RobustFitOptions& o) {
  if (!(o.c > 0)) fail("robust fit: tuning constant c must be > 0 (got ", o.c, ")");
  if (o.max_iter < 1) fail("robust fit: max_iter must be >= 1 (got ", o.max_iter, ")");
  const int F = batch.fillets;
  std::vector<BatchFit> out(static_cast<size_t>(F));
  std::vector<State> st(static_cast<size_t>(F));
  std::vector<FilletModel> models(static_cast<size_t>(F));
  FilletBatch b = batch;
  b.models = models.data();
  check_fillet_batch(b);
  const size_t n_px = size_t(b.pixels());
  std::vector<double> r(n_px), sums(size_t(F) * IRLS_SUMS), tmp;
  auto range = [&](int f) { return std::pair{b.offsets[f], b.offsets[f + 1]}; };
  auto fail_fit = [&](int f, std::string why) {
    out[f].error = std::move(why);
    st[f].active = false;
  };
  for (int f = 0; f < F; ++f) {
    size_t n = 0;
    bool finite = true;
    for (int i = b.offsets[f]; i < b.offsets[f + 1]; ++i)
      if (b.use[i]) {
        ++n;
        finite &= std::isfinite(b.thickness[i]) && b.xray[i] > 0;
        st[f].t_lo = std::min(st[f].t_lo, double(b.thickness[i]));
        st[f].t_hi = std::max(st[f].t_hi, double(b.thickness[i]));
      }
    out[f].fit.n = n;
    st[f].active = true;
    if (n < 3)
      fail_fit(f, "robust fit needs at least 3 points, got " + std::to_string(n));
    else if (!finite)
      fail_fit(f, "robust fit: a point is not finite");
    models[f] = {0, 0, 0, o.c, 0, 0};
  }
  // The OLS start: weights 1.
  backend.irls_sums(b, r.data(), sums.data());
  for (int f = 0; f < F; ++f) {
    if (!st[f].active) continue;
    if (!line_from(&sums[size_t(f) * IRLS_SUMS], st[f].b0, st[f].b1))
      fail_fit(f, "robust fit: all points share one thickness");
    models[f] = {st[f].b0, st[f].b1, 0, o.c, 0, 0};
  }
  // Residuals of the current lines (scale 0: the sums are not used).
  backend.irls_sums(b, r.data(), sums.data());
  for (int f = 0; f < F; ++f) {
    if (!st[f].active) continue;
    const auto [from, to] = range(f);
    st[f].scale = mad_scale(r.data(), b.use, from, to, tmp);
    st[f].dev_prev = deviance(r.data(), b.use, from, to, nullptr, o.c);
    out[f].fit.iterations = 1;
  }
  std::vector<double> r_prev;
  while (true) {
    // Fillets still iterating; a perfect fit of more than half of the points has converged.
    bool any = false;
    for (int f = 0; f < F; ++f) {
      if (!st[f].active) continue;
      if (st[f].scale == 0.0) {
        out[f].fit.converged = true;
        st[f].active = false;
        continue;
      }
      models[f] = {st[f].b0, st[f].b1, st[f].scale, o.c, 0, 0};
      any = true;
    }
    if (!any) break;
    // Weighted sums with the weights of the current residuals; the weights kept for the
    // deviance of the next line.
    r_prev = r;
    backend.irls_sums(b, r.data(), sums.data());
    for (int f = 0; f < F; ++f) {
      if (!st[f].active) continue;
      const auto [from, to] = range(f);
      st[f].w.clear();
      for (int i = from; i < to; ++i) {
        if (!b.use[i]) continue;
        const double z = r_prev[i] / st[f].scale / o.c;
        st[f].w.push_back(std::abs(z) <= 1 ? (1 - z * z) * (1 - z * z) : 0.0);
      }
      std::copy(st[f].prev, st[f].prev + 3, st[f].before);
      st[f].prev[0] = st[f].b0, st[f].prev[1] = st[f].b1;
      if (!line_from(&sums[size_t(f) * IRLS_SUMS], st[f].b0, st[f].b1)) {
        fail_fit(f,
                 "robust fit: every point but those at one thickness was rejected as an "
                 "outlier (" +
                     std::to_string(out[f].fit.n) + " points)");
        continue;
      }
      models[f] = {st[f].b0, st[f].b1, 0, o.c, 0, 0};
    }
    // Residuals of the new lines, their scale and deviance.
    backend.irls_sums(b, r.data(), sums.data());
    for (int f = 0; f < F; ++f) {
      if (!st[f].active) continue;
      const auto [from, to] = range(f);
      State& s = st[f];
      RobustFit& fit = out[f].fit;
      s.scale = mad_scale(r.data(), b.use, from, to, tmp);
      const double dev = deviance(r.data(), b.use, from, to, &s.w, o.c);
      ++fit.iterations;
      const double cur[3] = {s.b0, s.b1, 0};
      const bool settled = fit_settled(o, dev, s.dev_prev, s.before, s.prev, cur, s.t_lo, s.t_hi,
                                       s.scale, fit.iterations);
      s.dev_prev = dev;
      if (settled) {
        fit.converged = true;
        s.active = false;
      } else if (fit.iterations >= o.max_iter) {
        s.active = false;
      }
    }
  }
  for (int f = 0; f < F; ++f) {
    if (!out[f].error.empty()) continue;
    RobustFit& fit = out[f].fit;
    fit.beta0 = st[f].b0;
    fit.beta1 = st[f].b1;
    fit.scale = st[f].scale;
    const auto [from, to] = range(f);
    for (int i = from; i < to; ++i)
      if (b.use[i]) fit.inliers += fit.scale > 0 ? std::abs(r[i] / fit.scale) <= o.c : 1;
  }
  return out;
}

}  // namespace rangex
