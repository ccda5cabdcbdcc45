#include "pipeline/pseudo_xray.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace rangex {

namespace {
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
}  // namespace

void check_fillet_batch(const FilletBatch& b) {
  if (b.fillets < 0) fail("fillet batch: ", b.fillets, " fillets");
  if (b.fillets == 0) return;
  if (!b.offsets || b.offsets[0] != 0) fail("fillet batch: offsets must start at 0");
  for (int f = 0; f < b.fillets; ++f) {
    if (b.offsets[f + 1] < b.offsets[f])
      fail("fillet batch: offsets fall at fillet ", f, " (", b.offsets[f], " then ",
           b.offsets[f + 1], ")");
    const FilletModel& m = b.models[f];
    for (double v : {m.b0, m.b1, m.scale, m.c, m.noise_a, m.noise_b})
      if (!std::isfinite(v)) fail("fillet batch: the model of fillet ", f, " is not finite");
  }
}

void pseudo_xray_map(const FilletBatch& b, float* ln_p, float* p, float* residual, float* z) {
  check_fillet_batch(b);
  for (int f = 0; f < b.fillets; ++f) {
    const FilletModel& m = b.models[f];
    const bool noise = m.noise_a > 0 || m.noise_b > 0;
    for (int i = b.offsets[f]; i < b.offsets[f + 1]; ++i) {
      if (!b.use[i]) {
        ln_p[i] = p[i] = residual[i] = z[i] = kNaNf;
        continue;
      }
      const float lp = float(m.b0 + m.b1 * double(b.thickness[i]));
      const float pp = std::exp(lp);
      const float r = float(std::log(double(b.xray[i])) - double(lp));
      ln_p[i] = lp;
      p[i] = pp;
      residual[i] = r;
      if (noise) {
        const double I = pp, v = m.noise_a / I + m.noise_b / (I * I);
        z[i] = float(double(r) / std::sqrt(std::max(v, 1e-12)));
      } else {
        z[i] = kNaNf;
      }
    }
  }
}

void irls_sums(const FilletBatch& b, double* r, double* sums) {
  check_fillet_batch(b);
  for (int f = 0; f < b.fillets; ++f) {
    const FilletModel& m = b.models[f];
    double s[IRLS_SUMS] = {0, 0, 0, 0, 0, 0};
    for (int i = b.offsets[f]; i < b.offsets[f + 1]; ++i) {
      if (!b.use[i]) {
        r[i] = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      const double x = b.thickness[i], y = std::log(double(b.xray[i]));
      const double ri = y - (m.b0 + m.b1 * x);
      double w = 1;
      if (m.scale > 0) {
        const double u = ri / m.scale / m.c;
        w = std::abs(u) <= 1 ? (1 - u * u) * (1 - u * u) : 0.0;
      }
      r[i] = ri;
      s[0] += w;
      s[1] += w * x;
      s[2] += w * y;
      s[3] += w * x * x;
      s[4] += w * x * y;
      s[5] += w * ri * ri;
    }
    std::copy(s, s + IRLS_SUMS, sums + size_t(f) * IRLS_SUMS);
  }
}

}  // namespace rangex
