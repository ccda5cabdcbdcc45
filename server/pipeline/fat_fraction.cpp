#include "pipeline/fat_fraction.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/masked_smooth.h"

namespace rangex {

void fat_fraction_map(const float* lengths, const float* sigma, const uint8_t* mask, int rows,
                      int cols, double sigma_px, std::vector<float>& phi,
                      std::vector<float>& phi_var) {
  const size_t n = size_t(rows) * size_t(cols);
  std::vector<float> fat(n), soft(n), var(n), sf, ss, sv;
  std::vector<uint8_t> m(n);
  for (size_t p = 0; p < n; ++p) {
    const float l = lengths[3 * p], f = lengths[3 * p + 1];
    m[p] = mask[p] && std::isfinite(l) && std::isfinite(f);
    fat[p] = m[p] ? f : 0;
    soft[p] = m[p] ? l + f : 0;
    var[p] = m[p] ? sigma[3 * p + 1] * sigma[3 * p + 1] : 0;
  }
  masked_gaussian(fat.data(), m.data(), rows, cols, sigma_px, sf);
  masked_gaussian(soft.data(), m.data(), rows, cols, sigma_px, ss);
  masked_gaussian(var.data(), m.data(), rows, cols, sigma_px, sv);
  // The smoothed fat's variance: the neighbourhood's mean variance times the kernel's
  // white-noise gain squared (the pixels' noise is independent; more at the mask's edge).
  const double g2 = gaussian_noise_gain(sigma_px) * gaussian_noise_gain(sigma_px);
  phi.assign(n, std::numeric_limits<float>::quiet_NaN());
  phi_var.assign(n, std::numeric_limits<float>::quiet_NaN());
  for (size_t p = 0; p < n; ++p)
    if (mask[p] && std::isfinite(sf[p]) && ss[p] > 0) {
      phi[p] = std::clamp(sf[p] / ss[p], 0.f, 1.f);
      phi_var[p] = float(g2 * sv[p] / (double(ss[p]) * ss[p]));
    }
}

}  // namespace rangex
