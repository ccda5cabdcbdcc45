#include "pipeline/robust_fit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/error.h"

namespace rangex {

double median_inplace(double* v, size_t n) {
  if (n == 0) return std::numeric_limits<double>::quiet_NaN();
  const size_t h = n / 2;
  std::nth_element(v, v + h, v + n);
  const double hi = v[h];
  if (n % 2) return hi;
  return 0.5 * (hi + *std::max_element(v, v + h));
}

namespace {

constexpr double kMadNormal = 0.6744897501960817;  // Gaussian 3/4 quantile

struct Line {
  double b0, b1;
};

// Weighted least squares on the 2x2 normal equations (centred for conditioning).
bool weighted_line(const double* x, const double* y, const double* w, size_t n, Line& out) {
  double sw = 0, sx = 0, sy = 0;
  for (size_t i = 0; i < n; ++i) {
    const double wi = w ? w[i] : 1.0;
    sw += wi;
    sx += wi * x[i];
    sy += wi * y[i];
  }
  if (!(sw > 0)) return false;
  const double mx = sx / sw, my = sy / sw;
  double sxx = 0, sxy = 0;
  for (size_t i = 0; i < n; ++i) {
    const double wi = w ? w[i] : 1.0, dx = x[i] - mx;
    sxx += wi * dx * dx;
    sxy += wi * dx * (y[i] - my);
  }
  // No spread in x (relative to its size, so that rounding of the mean does not count).
  if (!(sxx > 1e-12 * sw * std::max(1.0, mx * mx))) return false;
  out.b1 = sxy / sxx;
  out.b0 = my - out.b1 * mx;
  return true;
}

}  // namespace

RobustFit fit_tukey_line(const double* x, const double* y, size_t n, const RobustFitOptions& o) {
  if (n < 3) fail("robust fit needs at least 3 points, got ", n);
  if (!(o.c > 0)) fail("robust fit: tuning constant c must be > 0 (got ", o.c, ")");
  if (o.max_iter < 1) fail("robust fit: max_iter must be >= 1 (got ", o.max_iter, ")");
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(x[i]) || !std::isfinite(y[i]))
      fail("robust fit: point ", i, " is not finite (", x[i], ", ", y[i], ")");
  Line line;
  if (!weighted_line(x, y, nullptr, n, line)) fail("robust fit: all points share one thickness");

  std::vector<double> r(n), w(n), tmp(n);
  auto residuals = [&] {
    for (size_t i = 0; i < n; ++i) r[i] = y[i] - (line.b0 + line.b1 * x[i]);
  };
  auto mad_scale = [&] {
    for (size_t i = 0; i < n; ++i) tmp[i] = std::abs(r[i]);
    return median_inplace(tmp.data(), n) / kMadNormal;
  };
  // Deviance as statsmodels computes it: sum rho(r / s_w) with s_w the weighted fit's
  // residual variance sum(w r^2) / (n - 2).
  auto deviance = [&](const double* wt) {
    double ss = 0;
    for (size_t i = 0; i < n; ++i) ss += (wt ? wt[i] : 1.0) * r[i] * r[i];
    const double sw = ss / double(n - 2);
    double d = 0, carry = 0;  // Kahan summation: the change between iterations is tiny
    for (size_t i = 0; i < n; ++i) {
      const double z = r[i] / sw / o.c;
      if (std::abs(z) > 1) continue;
      const double u = 1 - z * z;
      const double term = -u * u * u * o.c * o.c / 6 - carry;
      const double t = d + term;
      carry = (t - d) - term;
      d = t;
    }
    return d;
  };

  residuals();
  RobustFit f;
  f.n = n;
  f.scale = mad_scale();
  double dev_prev = deviance(nullptr);
  f.iterations = 1;
  while (true) {
    if (f.scale == 0.0) {  // a perfect fit of more than half of the points
      f.converged = true;
      break;
    }
    for (size_t i = 0; i < n; ++i) {
      const double z = r[i] / f.scale / o.c;
      w[i] = std::abs(z) <= 1 ? (1 - z * z) * (1 - z * z) : 0.0;
    }
    if (!weighted_line(x, y, w.data(), n, line))
      fail("robust fit: every point but those at one thickness was rejected as an outlier (", n,
           " points)");
    residuals();
    f.scale = mad_scale();
    const double dev = deviance(w.data());
    ++f.iterations;
    const double allowed = o.relative_tol ? o.tol * std::max(1.0, std::abs(dev)) : o.tol;
    const bool settled = std::abs(dev - dev_prev) <= allowed;
    dev_prev = dev;
    if (settled) {
      f.converged = true;
      break;
    }
    if (f.iterations >= o.max_iter) break;
  }
  f.beta0 = line.b0;
  f.beta1 = line.b1;
  for (size_t i = 0; i < n; ++i) f.inliers += f.scale > 0 ? std::abs(r[i] / f.scale) <= o.c : 1;
  return f;
}

}  // namespace rangex
