#include "calib/scatter_constants.h"

#include <cmath>

#include "core/error.h"

namespace rangex {

ScatterFit fit_scatter_constants(const float* ref, const float* C, const float* a, size_t n) {
  // Closed-form least squares: K1 = mean(d); (K2off, K2) = OLS of d on [1, a], d = ref - C.
  double s = 0, sa = 0, saa = 0, sd = 0, sad = 0;
  size_t m = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(ref[i]) || !std::isfinite(C[i]) || !std::isfinite(a[i])) continue;
    const double d = double(ref[i]) - C[i];
    ++m;
    s += 1;
    sa += a[i];
    saa += double(a[i]) * a[i];
    sd += d;
    sad += a[i] * d;
  }
  if (m < 10) fail("scatter constants need at least 10 paired columns, got ", m);
  const double det = s * saa - sa * sa;
  if (det <= 1e-12 * s * s)
    fail("scatter constants: the stripe asymmetry does not vary over the samples");
  ScatterFit f;
  f.samples = m;
  f.constants.k1 = sd / s;
  f.constants.k2 = (s * sad - sa * sd) / det;
  f.constants.k2_offset = (sd - f.constants.k2 * sa) / s;
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(ref[i]) || !std::isfinite(C[i]) || !std::isfinite(a[i])) continue;
    const double d = double(ref[i]) - C[i];
    f.centroid_mae_px += std::abs(d);
    f.shifted_mae_px += std::abs(d - f.constants.k1);
    f.modified_mae_px += std::abs(d - f.constants.k2_offset - f.constants.k2 * a[i]);
  }
  f.centroid_mae_px /= double(m);
  f.shifted_mae_px /= double(m);
  f.modified_mae_px /= double(m);
  return f;
}

}  // namespace rangex
