#include "sim/meat_texture.h"

#include <algorithm>
#include <cmath>

namespace rangex::sim {

namespace {

// White noise smoothed by a Gaussian of sigma_x, sigma_b (mm), then scaled to unit std.
std::vector<float> field(Rng& rng, int nx, int nb, double pitch, double sx, double sb) {
  std::vector<float> v(size_t(nx) * nb), tmp(v.size());
  for (float& a : v) a = float(rng.normal());
  auto kernel = [&](double s) {
    const int r = std::max(1, int(std::ceil(3 * s / pitch)));
    std::vector<float> k(size_t(2 * r + 1));
    for (int i = -r; i <= r; ++i)
      k[size_t(i + r)] = float(std::exp(-0.5 * (i * pitch / s) * (i * pitch / s)));
    return k;
  };
  const auto kx = kernel(sx), kb = kernel(sb);
  const int rx = int(kx.size() / 2), rb = int(kb.size() / 2);
  for (int j = 0; j < nb; ++j)
    for (int i = 0; i < nx; ++i) {
      double s = 0;
      for (int d = -rx; d <= rx; ++d)
        s += kx[size_t(d + rx)] * v[size_t(j) * nx + std::clamp(i + d, 0, nx - 1)];
      tmp[size_t(j) * nx + i] = float(s);
    }
  for (int j = 0; j < nb; ++j)
    for (int i = 0; i < nx; ++i) {
      double s = 0;
      for (int d = -rb; d <= rb; ++d)
        s += kb[size_t(d + rb)] * tmp[size_t(std::clamp(j + d, 0, nb - 1)) * nx + i];
      v[size_t(j) * nx + i] = float(s);
    }
  double m = 0, q = 0;
  for (float a : v) m += a, q += double(a) * a;
  m /= double(v.size());
  const double sd = std::sqrt(std::max(1e-12, q / double(v.size()) - m * m));
  for (float& a : v) a = float((a - m) / sd);
  return v;
}

// The standard normal's upper quantile: z with P(Z > z) = p (bisection on erfc).
double upper_quantile(double p) {
  double lo = -8, hi = 8;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(mid / std::sqrt(2.0)) > p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

namespace {
double bilinear(const std::vector<float>& v, const MeatTexture& t, double x, double b) {
  if (v.empty()) return 0;
  const double fx = (x - t.x0) / t.pitch, fb = (b - t.b0) / t.pitch;
  if (fx < 0 || fb < 0 || fx >= t.nx - 1 || fb >= t.nb - 1) return 0;
  const int i = int(fx), j = int(fb);
  const double u = fx - i, w = fb - j;
  const float* r0 = &v[size_t(j) * t.nx + i];
  const float* r1 = r0 + t.nx;
  return (1 - w) * ((1 - u) * r0[0] + u * r0[1]) + w * ((1 - u) * r1[0] + u * r1[1]);
}
}  // namespace

double MeatTexture::at(double x, double b) const {
  return bilinear(factor, *this, x, b);
}

double MeatTexture::fat_at(double x, double b) const {
  return bilinear(fat, *this, x, b);
}

double MeatTexture::density_at(double x, double b) const {
  return (1 + at(x, b)) / (1 - contrast * fat_at(x, b)) - 1;
}

MeatTexture make_meat_texture(Rng& rng, double x_min, double x_max, double b_min, double b_max,
                              const MeatTextureParams& p) {
  MeatTexture t;
  if (p.texture_std <= 0 && p.marbling <= 0) return t;
  t.x0 = x_min - 1, t.b0 = b_min - 1;
  t.nx = int(std::ceil((x_max - x_min + 2) / t.pitch)) + 1;
  t.nb = int(std::ceil((b_max - b_min + 2) / t.pitch)) + 1;
  t.factor.assign(size_t(t.nx) * t.nb, 0.f);
  if (p.texture_std > 0) {
    // Two scales: fibres (about 1-2 mm) and bundles (3-5 mm), equally strong.
    const double fine = rng.uniform(0.5, 1.0), coarse = rng.uniform(1.5, 2.5);
    const auto a = field(rng, t.nx, t.nb, t.pitch, fine, fine);
    const auto b = field(rng, t.nx, t.nb, t.pitch, coarse, coarse);
    for (size_t i = 0; i < t.factor.size(); ++i)
      t.factor[i] = float(p.texture_std * (a[i] + b[i]) / std::sqrt(2.0));
  }
  if (p.marbling > 0) {
    // Streaks along the muscle (here along the belt, turned per fillet would need a
    // rotation the raster does not have): narrow across, long along.
    const auto m = field(rng, t.nx, t.nb, t.pitch, rng.uniform(0.5, 1.0), rng.uniform(2.0, 4.0));
    const double q = upper_quantile(p.marbling);
    t.fat.assign(t.factor.size(), 0.f);
    t.contrast = p.marbling_contrast;
    for (size_t i = 0; i < t.factor.size(); ++i) {
      const double fat = std::clamp((m[i] - q) / 0.5 + 0.5, 0.0, 1.0);
      t.fat[i] = float(fat);
      t.factor[i] = float((1 + t.factor[i]) * (1 - p.marbling_contrast * fat) - 1);
    }
  }
  return t;
}

}  // namespace rangex::sim
