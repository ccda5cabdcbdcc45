#include "pipeline/matched_kernels.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "pipeline/bright_enclosure.h"
#include "pipeline/thickness_spread.h"

namespace rangex {

namespace {
// Median and robust spread of z over the usable finite pixels (thickness_spread's, one bin);
// false when there are none.
bool robust_centre(const float* z, const uint8_t* use, size_t n, double& med, double& sd) {
  ThicknessBins one;
  one.members.emplace_back();
  for (size_t i = 0; i < n; ++i)
    if (use[i] && std::isfinite(z[i])) one.members[0].push_back(i);
  if (one.members[0].empty()) return false;
  one.centre_mm.push_back(0);
  const SpreadProfile s = spread_profile(std::vector<float>(z, z + n), one, 0);
  med = s.median[0], sd = s.scale[0];
  return sd > 0;
}

// In-place Cholesky of the m x m matrix a (lower triangle); false when not positive definite.
bool cholesky(std::vector<double>& a, size_t m) {
  for (size_t j = 0; j < m; ++j) {
    double d = a[j * m + j];
    for (size_t k = 0; k < j; ++k) d -= a[j * m + k] * a[j * m + k];
    if (!(d > 0)) return false;
    const double l = std::sqrt(d);
    a[j * m + j] = l;
    for (size_t i = j + 1; i < m; ++i) {
      double s = a[i * m + j];
      for (size_t k = 0; k < j; ++k) s -= a[i * m + k] * a[j * m + k];
      a[i * m + j] = s / l;
    }
  }
  return true;
}

// clip_bright, also handing back the median and spread it used; false (out all NaN) when
// there is no spread to measure against.
bool clip_bright_at(const float* z, const uint8_t* use, int rows, int cols, double clip, int reach,
                    double void_level, std::vector<float>& out, double& med, double& sd) {
  const size_t n = size_t(rows) * size_t(cols);
  out.assign(n, std::numeric_limits<float>::quiet_NaN());
  const bool ok = robust_centre(z, use, n, med, sd);
  const float top = ok ? float(med + clip * sd) : std::numeric_limits<float>::infinity();
  std::vector<float> excess;
  if (ok && reach > 0) bright_enclosure_excess(z, use, rows, cols, top, reach, excess);
  for (size_t i = 0; i < n; ++i)
    if (use[i] && std::isfinite(z[i]))
      out[i] = std::min(excess.empty() ? z[i] : z[i] - excess[i], top);
  if (!ok || !(void_level > 0)) return ok;
  // A void and the ring its blurred rim spills into: flat meat at the median.
  const float lid = float(med + void_level * sd);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const size_t i = size_t(r) * cols + c;
      if (!(use[i] && z[i] > lid)) continue;
      for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if (rr < 0 || rr >= rows || cc < 0 || cc >= cols) continue;
          float& o = out[size_t(rr) * cols + cc];
          if (std::isfinite(o)) o = float(med);
        }
    }
  return ok;
}
}  // namespace

void clip_bright(const float* z, const uint8_t* use, int rows, int cols, double clip, int reach,
                 double void_level, std::vector<float>& out) {
  double med = 0, sd = 0;
  clip_bright_at(z, use, rows, cols, clip, reach, void_level, out, med, sd);
}

double bright_quantile(const float* z, const uint8_t* use, size_t n, double q) {
  double med = 0, sd = 0;
  if (!robust_centre(z, use, n, med, sd)) return std::numeric_limits<double>::quiet_NaN();
  std::vector<float> v;
  for (size_t i = 0; i < n; ++i)
    if (use[i] && std::isfinite(z[i])) v.push_back(z[i]);
  const size_t k = std::min(v.size() - 1, size_t(std::clamp(q, 0.0, 1.0) * double(v.size())));
  std::nth_element(v.begin(), v.begin() + long(k), v.end());
  return (double(v[k]) - med) / sd;
}

double learned_void_level(std::vector<double> bright_quantiles, double factor, double clip) {
  bright_quantiles.erase(std::remove_if(bright_quantiles.begin(), bright_quantiles.end(),
                                        [](double x) { return !std::isfinite(x); }),
                         bright_quantiles.end());
  if (!(factor > 0) || bright_quantiles.empty()) return 0;
  const size_t m = bright_quantiles.size() / 2;
  std::nth_element(bright_quantiles.begin(), bright_quantiles.begin() + long(m),
                   bright_quantiles.end());
  return std::max(clip, factor * bright_quantiles[m]);
}

TextureCovariance::TextureCovariance(int max_lag, double clip, int reach, double void_level)
    : max_lag_(max_lag),
      clip_(clip),
      reach_(reach),
      void_level_(void_level),
      sum_(size_t(2 * max_lag + 1) * size_t(2 * max_lag + 1), 0.0),
      pairs_(sum_.size(), 0.0) {
  if (max_lag < 1 || max_lag > 16) fail("texture covariance: max_lag ", max_lag, " not in 1..16");
  if (reach < 0 || reach > 16) fail("texture covariance: reach ", reach, " not in 0..16");
  if (void_level < 0) fail("texture covariance: void level ", void_level, " below 0");
}

void TextureCovariance::add(const float* z, const uint8_t* use, int rows, int cols) {
  const size_t n = size_t(rows) * size_t(cols);
  double med = 0, sd = 0;
  std::vector<float> zc;
  if (!clip_bright_at(z, use, rows, cols, clip_, reach_, void_level_, zc, med, sd)) return;
  // Unit robust spread, prepared as detection prepares it (clip_bright), 0 (and not counted)
  // off the usable pixels.
  std::vector<double> v(n, 0.0), u(n, 0.0);
  for (size_t i = 0; i < n; ++i)
    if (std::isfinite(zc[i])) {
      v[i] = (zc[i] - med) / sd;
      u[i] = 1;
    }
  const int L = max_lag_, w = 2 * L + 1;
  for (int dr = -L; dr <= L; ++dr)
    for (int dc = -L; dc <= L; ++dc) {
      double s = 0, p = 0;
      for (int r = std::max(0, -dr); r < std::min(rows, rows - dr); ++r) {
        const double* a = &v[size_t(r) * cols];
        const double* ua = &u[size_t(r) * cols];
        const double* b = &v[size_t(r + dr) * cols];
        const double* ub = &u[size_t(r + dr) * cols];
        for (int c = std::max(0, -dc); c < std::min(cols, cols - dc); ++c) {
          s += a[c] * b[c + dc];
          p += ua[c] * ub[c + dc];
        }
      }
      sum_[size_t(dr + L) * w + size_t(dc + L)] += s;
      pairs_[size_t(dr + L) * w + size_t(dc + L)] += p;
    }
  ++fillets_;
}

double TextureCovariance::at(int drow, int dcol) const {
  if (std::abs(drow) > max_lag_ || std::abs(dcol) > max_lag_) return 0;
  const size_t k = size_t(drow + max_lag_) * size_t(2 * max_lag_ + 1) + size_t(dcol + max_lag_);
  return pairs_[k] > 0 ? sum_[k] / pairs_[k] : 0.0;
}

namespace {
// A piece's chord (mm) at (x across, y along; mm from the window's centre) averaged over each
// pixel of the window (8 x 8 rays), then blurred across the detector by blur_px.
template <class Chord>
std::vector<double> piece_profile(Chord chord, double pitch_mm, double step_mm, int radius,
                                  double blur_px) {
  const int w = 2 * radius + 1, ss = 8;
  std::vector<double> s(size_t(w) * w, 0.0);
  for (int i = 0; i < w; ++i)
    for (int j = 0; j < w; ++j) {
      double acc = 0;
      for (int a = 0; a < ss; ++a)
        for (int b = 0; b < ss; ++b) {
          const double y = (i - radius + (a + 0.5) / ss - 0.5) * step_mm;
          const double x = (j - radius + (b + 0.5) / ss - 0.5) * pitch_mm;
          acc += chord(x, y);
        }
      s[size_t(i) * w + j] = acc / (ss * ss);
    }
  if (blur_px > 0) {  // across the detector: along the rows of the window
    std::vector<double> k(static_cast<size_t>(w), 0.0), out(s.size(), 0.0);
    double ks = 0;
    for (int d = -radius; d <= radius; ++d)
      ks += k[size_t(d + radius)] = std::exp(-0.5 * d * d / (blur_px * blur_px));
    for (int i = 0; i < w; ++i)
      for (int j = 0; j < w; ++j)
        for (int d = -radius; d <= radius; ++d)
          if (j + d >= 0 && j + d < w)
            out[size_t(i) * w + j] += k[size_t(d + radius)] / ks * s[size_t(i) * w + j + d];
    s = std::move(out);
  }
  return s;
}

// One diameter's kernels: each length along kNeedleDirections directions.
void learn_needles_of(const TextureCovariance& c, const std::vector<double>& lengths_mm,
                      double diam_mm, double pitch_mm, double step_mm, double blur_px,
                      MatchedKernels& k) {
  for (double len : lengths_mm) {
    const int r = kernel_radius(len, pitch_mm, step_mm);
    if (2 * r > c.max_lag())
      fail("needle kernels: a ", len, " mm needle needs a window of radius ", r,
           " px, the texture was measured to lags of ", c.max_lag(), " px");
    for (int d = 0; d < kNeedleDirections; ++d) {
      const double deg = 180.0 * d / kNeedleDirections;
      k.needle_diameters_mm.push_back(diam_mm);
      k.needle_lengths_mm.push_back(len);
      k.needle_angles_deg.push_back(deg);
      k.needle_radii.push_back(r);
      k.needle_taps.push_back(whitened_kernel(
          c, needle_profile(len, diam_mm, deg * M_PI / 180, pitch_mm, step_mm, r, blur_px), r));
      k.needle_spreads.push_back(kernel_spread(c, k.needle_taps.back(), r));
    }
  }
}

}  // namespace

std::vector<double> sphere_profile(double d_mm, double pitch_mm, double step_mm, int radius,
                                   double blur_px) {
  const double R2 = 0.25 * d_mm * d_mm;
  return piece_profile(
      [R2](double x, double y) { return 2 * std::sqrt(std::max(0.0, R2 - x * x - y * y)); },
      pitch_mm, step_mm, radius, blur_px);
}

std::vector<double> needle_profile(double len_mm, double diam_mm, double angle_rad, double pitch_mm,
                                   double step_mm, int radius, double blur_px) {
  const double R2 = 0.25 * diam_mm * diam_mm, ux = std::cos(angle_rad), uy = std::sin(angle_rad);
  return piece_profile(
      [=](double x, double y) {
        const double along = x * ux + y * uy, across = y * ux - x * uy;
        if (std::abs(along) > 0.5 * len_mm) return 0.0;
        return 2 * std::sqrt(std::max(0.0, R2 - across * across));
      },
      pitch_mm, step_mm, radius, blur_px);
}

std::vector<double> whitened_kernel(const TextureCovariance& c, const std::vector<double>& s,
                                    int radius) {
  const int w = 2 * radius + 1;
  const size_t m = size_t(w) * w;
  if (s.size() != m) fail("whitened kernel: a profile of ", s.size(), " taps for radius ", radius);
  if (2 * radius > c.max_lag())
    fail("whitened kernel: radius ", radius, " needs lags to ", 2 * radius, ", measured to ",
         c.max_lag());
  const double var = c.at(0, 0);
  if (!(var > 0)) fail("whitened kernel: no texture measured (no usable pixels)");
  std::vector<double> a(m * m);
  for (double ridge = 1e-3 * var;; ridge *= 10) {
    for (size_t p = 0; p < m; ++p)
      for (size_t q = 0; q < m; ++q) {
        const int dr = int(p / w) - int(q / w), dc = int(p % w) - int(q % w);
        a[p * m + q] = c.at(dr, dc) + (p == q ? ridge : 0.0);
      }
    if (cholesky(a, m)) break;
    if (ridge > var) fail("whitened kernel: the measured covariance is not positive definite");
  }
  // L L^T h = s.
  std::vector<double> h(s);
  for (size_t i = 0; i < m; ++i) {
    for (size_t k = 0; k < i; ++k) h[i] -= a[i * m + k] * h[k];
    h[i] /= a[i * m + i];
  }
  for (size_t i = m; i-- > 0;) {
    for (size_t k = i + 1; k < m; ++k) h[i] -= a[k * m + i] * h[k];
    h[i] /= a[i * m + i];
  }
  double hs = 0;
  for (size_t i = 0; i < m; ++i) hs += h[i] * s[i];
  for (double& x : h) x /= hs;
  return h;
}

double kernel_spread(const TextureCovariance& c, const std::vector<double>& taps, int radius) {
  const int w = 2 * radius + 1;
  double q = 0;
  for (size_t p = 0; p < taps.size(); ++p)
    for (size_t k = 0; k < taps.size(); ++k)
      q += taps[p] * taps[k] * c.at(int(p / w) - int(k / w), int(p % w) - int(k % w));
  return std::sqrt(std::max(0.0, q));
}

int kernel_radius(double d_mm, double pitch_mm, double step_mm) {
  const double px = std::min(pitch_mm, step_mm);
  if (!(d_mm > 0 && px > 0)) fail("matched kernels: a ", d_mm, " mm sphere on ", px, " mm pixels");
  return std::max(kBaseKernelRadius, int(std::ceil(0.5 * d_mm / px - 1e-9)));
}

MatchedKernels learn_matched_kernels(const TextureCovariance& c,
                                     const std::vector<double>& sizes_mm, double pitch_mm,
                                     double step_mm, double blur_px) {
  MatchedKernels k;
  k.clip = c.clip();  // inspection clips as the texture was measured
  k.enclosure_px = c.reach();
  k.void_level = c.void_level();
  for (double d : sizes_mm) {
    const int r = kernel_radius(d, pitch_mm, step_mm);
    if (2 * r > c.max_lag())
      fail("matched kernels: a ", d, " mm sphere needs a window of radius ", r,
           " px, the texture was measured to lags of ", c.max_lag(), " px");
    k.sizes_mm.push_back(d);
    k.radii.push_back(r);
    k.taps.push_back(whitened_kernel(c, sphere_profile(d, pitch_mm, step_mm, r, blur_px), r));
    k.spreads.push_back(kernel_spread(c, k.taps.back(), r));
  }
  return k;
}

void learn_needle_kernels(const TextureCovariance& c, const std::vector<double>& lengths_mm,
                          const std::vector<double>& diameters_mm, double pitch_mm, double step_mm,
                          double blur_px, MatchedKernels& k) {
  for (double diam_mm : diameters_mm) {
    if (!(diam_mm > 0)) fail("needle kernels: a needle of diameter ", diam_mm, " mm");
    learn_needles_of(c, lengths_mm, diam_mm, pitch_mm, step_mm, blur_px, k);
  }
}

namespace {
// A row of outputs is taken kBlock columns at a time, every tap summed into the block before
// the next: the block's sums stay in registers instead of going through memory once per tap.
// The last block of a row may read past the row's end, into padding or the slack; what it
// sums there is never written.
constexpr int kBlock = 32;
}  // namespace

PaddedField pad_field(const float* z, const uint8_t* use, int rows, int cols, int radius) {
  PaddedField f;
  f.rows = rows, f.cols = cols, f.radius = radius;
  f.pitch = size_t(cols) + 2 * size_t(radius);
  f.v.assign((size_t(rows) + 2 * size_t(radius)) * f.pitch + kBlock, 0.0);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const size_t i = size_t(r) * cols + c;
      if (use[i] && std::isfinite(z[i]))
        f.v[size_t(r + radius) * f.pitch + size_t(c + radius)] = z[i];
    }
  return f;
}

double apply_kernel(const PaddedField& f, const uint8_t* use, const std::vector<double>& taps,
                    int radius, std::vector<float>& out) {
  if (radius > f.radius) fail("apply_kernel: radius ", radius, " beyond the padding's ", f.radius);
  const int w = 2 * radius + 1, rows = f.rows, cols = f.cols;
  const size_t n = size_t(rows) * size_t(cols);
  // Each pixel sums its taps in the same order as the direct sum over its window, so the
  // outputs are the same whatever the padding.
  const size_t skip = size_t(f.radius - radius);
  out.assign(n, std::numeric_limits<float>::quiet_NaN());
  for (int r = 0; r < rows; ++r) {
    const uint8_t* u = use + size_t(r) * cols;
    for (int c0 = 0; c0 < cols; c0 += kBlock) {
      const int m = std::min(kBlock, cols - c0);
      if (std::none_of(u + c0, u + c0 + m, [](uint8_t x) { return x != 0; })) continue;
      double acc[kBlock] = {};
      for (int i = 0; i < w; ++i) {
        const double* row = &f.v[(size_t(r + i) + skip) * f.pitch + size_t(c0) + skip];
        const double* h = &taps[size_t(i) * w];
        for (int j = 0; j < w; ++j) {
          const double hj = h[j];
          const double* src = row + j;
          for (int k = 0; k < kBlock; ++k) acc[k] += hj * src[k];
        }
      }
      for (int k = 0; k < m; ++k)
        if (u[c0 + k]) out[size_t(r) * cols + size_t(c0 + k)] = float(acc[k]);
    }
  }
  double g = 0;
  for (double h : taps) g += h * h;
  return std::sqrt(g);
}

double apply_kernel(const float* z, const uint8_t* use, int rows, int cols,
                    const std::vector<double>& taps, int radius, std::vector<float>& out) {
  return apply_kernel(pad_field(z, use, rows, cols, radius), use, taps, radius, out);
}

double apply_kernel_at(const float* z, const uint8_t* use, int rows, int cols,
                       const std::vector<double>& taps, int radius, int r, int c) {
  const int w = 2 * radius + 1;
  double a = 0;
  for (int i = 0; i < w; ++i)
    for (int j = 0; j < w; ++j) {
      const int rr = r + i - radius, cc = c + j - radius;
      if (rr < 0 || rr >= rows || cc < 0 || cc >= cols) continue;
      const size_t k = size_t(rr) * size_t(cols) + size_t(cc);
      if (use[k] && std::isfinite(z[k])) a += taps[size_t(i) * w + size_t(j)] * z[k];
    }
  return a;
}

}  // namespace rangex
