#include "pipeline/robust_fit.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "core/error.h"

namespace rangex {

namespace {
// The values at ranks r0 <= r1 of v (as a full sort would place them). A strided sample of
// v brackets those ranks (Floyd and Rivest's idea); one pass counts what lies below the
// bracket and gathers what lies in it, and only that small set is selected in. When the
// bracket misses (a sample that is not like the whole), every value is selected in. Exact
// either way. Empty when v holds a NaN. The bracket's ends are selected in the sample, not
// sorted, and the pass has no branch on the data (a value is written, then kept or not): on
// bins of 12,000 values this took 70-75 us against 175 us for nth_element alone.
template <class T>
std::optional<std::pair<T, T>> select_two_ranks(const T* v, size_t n, size_t r0, size_t r1) {
  auto finish = [&](T* in, size_t m, size_t below) {
    std::nth_element(in, in + long(r1 - below), in + m);
    const T v1 = in[r1 - below];
    if (r0 == r1) return std::pair{v1, v1};
    return std::pair{*std::max_element(in, in + long(r1 - below)), v1};
  };
  constexpr size_t kSample = 1024;
  std::vector<T> sample(kSample);
  for (size_t k = 0; k < kSample; ++k) sample[k] = v[(2 * k + 1) * n / (2 * kSample)];
  // Ranks within the sample, widened by about four standard deviations of a sampled rank.
  const double margin = 4 * std::sqrt(double(kSample)) / 2;
  const long k0 = long(std::floor(double(r0) / double(n) * kSample - margin)),
             k1 = long(std::ceil(double(r1) / double(n) * kSample + margin));
  T lo = -std::numeric_limits<T>::infinity(), hi = std::numeric_limits<T>::infinity();
  auto first = sample.begin();
  if (k0 >= 0) {
    std::nth_element(first, first + k0, sample.end());
    lo = sample[size_t(k0)];
    first += k0 + 1;
  }
  if (k1 < long(kSample)) {
    std::nth_element(first, sample.begin() + k1, sample.end());
    hi = sample[size_t(k1)];
  }
  const std::unique_ptr<T[]> in = std::make_unique_for_overwrite<T[]>(n);  // no zeros to write
  size_t below = 0, above = 0, m = 0;
  for (size_t i = 0; i < n; ++i) {
    const T x = v[i];
    below += x < lo;
    above += x > hi;
    in[m] = x;
    m += size_t((x >= lo) & (x <= hi));
  }
  if (below + above + m != n) return std::nullopt;  // a NaN compares as nothing
  if (below <= r0 && below + m > r1) return finish(in.get(), m, below);
  std::copy(v, v + n, in.get());
  return finish(in.get(), n, 0);
}

// Float values select as their doubles would (the conversion keeps their order), and the two
// middle values are averaged in double: either overload gives the same median of the same
// values.
template <class T>
double median_of(T* v, size_t n) {
  if (n == 0) return std::numeric_limits<double>::quiet_NaN();
  const size_t h = n / 2;
  if (n >= 4096)
    if (const auto ab = select_two_ranks(v, n, n % 2 ? h : h - 1, h))
      return n % 2 ? double(ab->second) : 0.5 * (double(ab->first) + double(ab->second));
  std::nth_element(v, v + h, v + n);
  const double hi = v[h];
  if (n % 2) return hi;
  return 0.5 * (hi + double(*std::max_element(v, v + h)));
}
}  // namespace

double median_inplace(double* v, size_t n) {
  return median_of(v, n);
}
double median_inplace(float* v, size_t n) {
  return median_of(v, n);
}

namespace {

// ln I = b[0] + b[1] T (+ b[2] T^2).
struct Poly {
  int degree = 1;
  double b[3] = {0, 0, 0};
  double at(double x) const { return degree == 1 ? b[0] + b[1] * x : b[0] + x * (b[1] + b[2] * x); }
};

// Weighted least squares on the 2x2 normal equations (centred for conditioning).
bool weighted_line(const double* x, const double* y, const double* w, size_t n, Poly& out) {
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
  out.b[1] = sxy / sxx;
  out.b[0] = my - out.b[1] * mx;
  return true;
}

// Weighted least squares of a parabola: the 3x3 normal equations in u = (x - m) / sd
// (conditioning: m and sd are the unweighted mean and spread of x, found once per fit so
// that each iteration is one pass), solved by elimination with partial pivoting, then
// carried back to x.
struct Centre {
  double m = 0, sd = 1;
};

bool weighted_parabola(const double* x, const double* y, const double* w, size_t n,
                       const Centre& ctr, Poly& out) {
  const double m = ctr.m, s = ctr.sd;
  // The moments sum(w u^k), k = 0..4, and sum(w u^k y), k = 0..2, in one pass.
  double s0 = 0, s1 = 0, s2 = 0, s3 = 0, s4 = 0, t0 = 0, t1 = 0, t2 = 0;
  const double inv = 1 / s;
  for (size_t i = 0; i < n; ++i) {
    const double wi = w ? w[i] : 1.0;
    const double u = (x[i] - m) * inv, wu = wi * u, wu2 = wu * u;
    s0 += wi, s1 += wu, s2 += wu2, s3 += wu2 * u, s4 += wu2 * u * u;
    t0 += wi * y[i], t1 += wu * y[i], t2 += wu2 * y[i];
  }
  const double sw = s0;
  if (!(sw > 0)) return false;
  double a[3][4] = {{s0, s1, s2, t0}, {s1, s2, s3, t1}, {s2, s3, s4, t2}};
  for (int k = 0; k < 3; ++k) {
    int piv = k;
    for (int r = k + 1; r < 3; ++r)
      if (std::abs(a[r][k]) > std::abs(a[piv][k])) piv = r;
    // Fewer than three distinct x with weight: the parabola is not determined.
    if (!(std::abs(a[piv][k]) > 1e-10 * sw)) return false;
    std::swap(a[k], a[piv]);
    for (int r = k + 1; r < 3; ++r) {
      const double f = a[r][k] / a[k][k];
      for (int c = k; c < 4; ++c) a[r][c] -= f * a[k][c];
    }
  }
  double c[3];
  for (int k = 2; k >= 0; --k) {
    double v = a[k][3];
    for (int j = k + 1; j < 3; ++j) v -= a[k][j] * c[j];
    c[k] = v / a[k][k];
  }
  out.b[2] = c[2] / (s * s);
  out.b[1] = c[1] / s - 2 * c[2] * m / (s * s);
  out.b[0] = c[0] - c[1] * m / s + c[2] * m * m / (s * s);
  return true;
}

bool weighted_poly(const double* x, const double* y, const double* w, size_t n, const Centre& ctr,
                   Poly& out) {
  return out.degree == 1 ? weighted_line(x, y, w, n, out) : weighted_parabola(x, y, w, n, ctr, out);
}

}  // namespace

double fit_move(const double prev[3], const double cur[3], double lo, double hi) {
  double most = 0;
  for (const double t : {lo, 0.5 * (lo + hi), hi}) {
    const double d = (cur[0] - prev[0]) + t * ((cur[1] - prev[1]) + t * (cur[2] - prev[2]));
    most = std::max(most, std::abs(d));
  }
  return most;
}

bool fit_settled(const RobustFitOptions& o, double dev, double dev_prev, const double before[3],
                 const double prev[3], const double cur[3], double lo, double hi, double scale,
                 int iterations) {
  const double allowed = o.relative_tol ? o.tol * std::max(1.0, std::abs(dev)) : o.tol;
  if (std::abs(dev - dev_prev) <= allowed) return true;
  if (!o.relative_tol || !(o.settled_move > 0)) return false;
  const double move = o.settled_move * scale;
  return fit_move(prev, cur, lo, hi) <= move ||
         (iterations > 2 && fit_move(before, cur, lo, hi) <= move);
}

RobustFit fit_tukey_line(const double* x, const double* y, size_t n, const RobustFitOptions& o) {
  return fit_tukey_poly(x, y, n, 1, o);
}

RobustFit fit_tukey_poly(const double* x, const double* y, size_t n, int degree,
                         const RobustFitOptions& o) {
  if (degree != 1 && degree != 2) fail("robust fit: degree must be 1 or 2 (got ", degree, ")");
  const size_t params = size_t(degree) + 1;
  if (n < params + 1) fail("robust fit needs at least ", params + 1, " points, got ", n);
  if (!(o.c > 0)) fail("robust fit: tuning constant c must be > 0 (got ", o.c, ")");
  if (o.max_iter < 1) fail("robust fit: max_iter must be >= 1 (got ", o.max_iter, ")");
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(x[i]) || !std::isfinite(y[i]))
      fail("robust fit: point ", i, " is not finite (", x[i], ", ", y[i], ")");
  Poly line;
  line.degree = degree;
  Centre ctr;
  if (degree == 2) {
    double sx = 0, sxx = 0;
    for (size_t i = 0; i < n; ++i) sx += x[i];
    ctr.m = sx / double(n);
    for (size_t i = 0; i < n; ++i) sxx += (x[i] - ctr.m) * (x[i] - ctr.m);
    ctr.sd = std::sqrt(sxx / double(n));
  }
  if ((degree == 2 && !(ctr.sd > 1e-6 * std::max(1.0, std::abs(ctr.m)))) ||
      !weighted_poly(x, y, nullptr, n, ctr, line))
    fail(degree == 1 ? "robust fit: all points share one thickness"
                     : "robust fit: fewer than three distinct thicknesses for a parabola");

  std::vector<double> r(n), w(n), tmp(n);
  // One pass: the residuals, their magnitudes (for the MAD) and sum(wt r^2) (the deviance's).
  double ss = 0;
  auto residuals = [&](const double* wt) {
    ss = 0;
    for (size_t i = 0; i < n; ++i) {
      r[i] = y[i] - line.at(x[i]);
      tmp[i] = std::abs(r[i]);
      ss += (wt ? wt[i] : 1.0) * r[i] * r[i];
    }
  };
  auto mad_scale = [&] { return median_inplace(tmp.data(), n) / kMadNormal; };
  // Deviance as statsmodels computes it: sum rho(r / s_w) with s_w the weighted fit's
  // residual variance sum(w r^2) / (n - parameters).
  auto deviance = [&] {
    const double sw = ss / double(n - params);
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

  const auto [x_lo, x_hi] = std::minmax_element(x, x + n);
  residuals(nullptr);
  RobustFit f;
  f.n = n;
  f.scale = mad_scale();
  double dev_prev = deviance();
  Poly prev = line, before_prev = line;  // the curves one and two iterations back
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
    before_prev = prev;
    prev = line;
    if (!weighted_poly(x, y, w.data(), n, ctr, line))
      fail("robust fit: every point but those at ",
           degree == 1 ? "one thickness" : "two thicknesses", " was rejected as an outlier (", n,
           " points)");
    residuals(w.data());
    f.scale = mad_scale();
    const double dev = deviance();
    ++f.iterations;
    const bool settled = fit_settled(o, dev, dev_prev, before_prev.b, prev.b, line.b, *x_lo, *x_hi,
                                     f.scale, f.iterations);
    dev_prev = dev;
    if (settled) {
      f.converged = true;
      break;
    }
    if (f.iterations >= o.max_iter) break;
  }
  f.beta0 = line.b[0];
  f.beta1 = line.b[1];
  f.beta2 = degree == 2 ? line.b[2] : 0.0;
  for (size_t i = 0; i < n; ++i) f.inliers += f.scale > 0 ? std::abs(r[i] / f.scale) <= o.c : 1;
  return f;
}

}  // namespace rangex
