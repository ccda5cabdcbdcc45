#include "pipeline/dual_energy.h"

#include <cmath>
#include <limits>

namespace rangex {

void dual_energy_terms(double u, double v, double* t) {
  int k = 0;
  for (int d = 0; d <= DE_DEGREE; ++d)
    for (int j = 0; j <= d; ++j) t[k++] = std::pow(u, d - j) * std::pow(v, j);
}

double dual_energy_poly(const double* c, double u, double v) {
  double t[DE_TERMS];
  dual_energy_terms(u, v, t);
  double s = 0;
  for (int i = 0; i < DE_TERMS; ++i) s += c[i] * t[i];
  return s;
}

void dual_energy_gradient(const double* c, double u, double v, double* du, double* dv) {
  double gu = 0, gv = 0;
  int k = 0;
  for (int d = 0; d <= DE_DEGREE; ++d)
    for (int j = 0; j <= d; ++j, ++k) {
      const int i = d - j;
      if (i > 0) gu += c[k] * i * std::pow(u, i - 1) * std::pow(v, j);
      if (j > 0) gv += c[k] * j * std::pow(u, i) * std::pow(v, j - 1);
    }
  *du = gu, *dv = gv;
}

bool dual_energy_invert(const DualEnergyParams& k, double x, double y, double* a, double* b,
                        double jinv[4]) {
  // The linear terms' inverse starts it; a fixed number of steps (a kernel's loop).
  double det = k.low[1] * k.high[2] - k.low[2] * k.high[1];
  double u = (k.high[2] * (x - k.low[0]) - k.low[2] * (y - k.high[0])) / det;
  double v = (k.low[1] * (y - k.high[0]) - k.high[1] * (x - k.low[0])) / det;
  double lu = 0, lv = 0, hu = 0, hv = 0;
  for (int it = 0; it < DE_NEWTON; ++it) {
    const double fx = dual_energy_poly(k.low, u, v) - x, fy = dual_energy_poly(k.high, u, v) - y;
    dual_energy_gradient(k.low, u, v, &lu, &lv);
    dual_energy_gradient(k.high, u, v, &hu, &hv);
    det = lu * hv - lv * hu;
    u -= (hv * fx - lv * fy) / det;
    v -= (lu * fy - hu * fx) / det;
  }
  dual_energy_gradient(k.low, u, v, &lu, &lv);
  dual_energy_gradient(k.high, u, v, &hu, &hv);
  det = lu * hv - lv * hu;
  // d(A, B) / d(x, y), in mm.
  jinv[0] = DE_A_MM * hv / det, jinv[1] = -DE_A_MM * lv / det;
  jinv[2] = -DE_B_MM * hu / det, jinv[3] = DE_B_MM * lu / det;
  *a = DE_A_MM * u, *b = DE_B_MM * v;
  const double rx = dual_energy_poly(k.low, u, v) - x, ry = dual_energy_poly(k.high, u, v) - y;
  return std::isfinite(u) && std::isfinite(v) && std::abs(rx) < 1e-6 && std::abs(ry) < 1e-6;
}

void dual_energy_decompose(const DualEnergyBatch& b, const DualEnergyParams& k, float* lengths,
                           float* sigma) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int p = 0; p < b.pixels; ++p) {
    float* out = lengths + 3 * p;
    float* sd = sigma + 3 * p;
    out[0] = out[1] = out[2] = sd[0] = sd[1] = sd[2] = nan;
    const double lo = b.low[p], hi = b.high[p];
    if ((b.use && !b.use[p]) || lo <= 0 || hi <= 0 || !(b.open_low[p] > 0) || !(b.open_high[p] > 0))
      continue;
    const double x = std::log(b.open_low[p] / lo), y = std::log(b.open_high[p] / hi);
    double A, B, J[4];
    if (!dual_energy_invert(k, x, y, &A, &B, J)) continue;
    const double T = b.thickness[p];
    const double* m = k.minv;
    for (int r = 0; r < 3; ++r) out[r] = float(m[3 * r] * A + m[3 * r + 1] * B + m[3 * r + 2] * T);
    // Covariance of (A, B): the counts through the inverse's Jacobian, plus the calibration's.
    const double vx = (k.gain_low * lo + k.var_e_low) / (lo * lo),
                 vy = (k.gain_high * hi + k.var_e_high) / (hi * hi);
    const double caa = J[0] * J[0] * vx + J[1] * J[1] * vy + k.var_a;
    const double cbb = J[2] * J[2] * vx + J[3] * J[3] * vy + k.var_b;
    const double cab = J[0] * J[2] * vx + J[1] * J[3] * vy;
    for (int r = 0; r < 3; ++r) {
      const double u = m[3 * r], v = m[3 * r + 1], w = m[3 * r + 2];
      sd[r] = float(std::sqrt(u * u * caa + 2 * u * v * cab + v * v * cbb + w * w * k.var_t));
    }
  }
}

}  // namespace rangex
