#include "pipeline/dual_energy.h"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "core/error.h"

namespace rangex {

namespace {
// x^0 .. x^DE_DEGREE by products (a kernel's loop; pow costs 50x more).
void powers(double x, double* p) {
  p[0] = 1;
  for (int i = 1; i <= DE_DEGREE; ++i) p[i] = p[i - 1] * x;
}
}  // namespace

void dual_energy_terms(double u, double v, double* t) {
  double pu[DE_DEGREE + 1], pv[DE_DEGREE + 1];
  powers(u, pu);
  powers(v, pv);
  int k = 0;
  for (int d = 0; d <= DE_DEGREE; ++d)
    for (int j = 0; j <= d; ++j) t[k++] = pu[d - j] * pv[j];
}

double dual_energy_poly(const double* c, double u, double v) {
  double t[DE_TERMS];
  dual_energy_terms(u, v, t);
  double s = 0;
  for (int i = 0; i < DE_TERMS; ++i) s += c[i] * t[i];
  return s;
}

void dual_energy_gradient(const double* c, double u, double v, double* du, double* dv) {
  double pu[DE_DEGREE + 1], pv[DE_DEGREE + 1];
  powers(u, pu);
  powers(v, pv);
  double gu = 0, gv = 0;
  int k = 0;
  for (int d = 0; d <= DE_DEGREE; ++d)
    for (int j = 0; j <= d; ++j, ++k) {
      const int i = d - j;
      if (i > 0) gu += c[k] * i * pu[i - 1] * pv[j];
      if (j > 0) gv += c[k] * j * pu[i] * pv[j - 1];
    }
  *du = gu, *dv = gv;
}

namespace {
void check_params(const DualEnergyParams& k) {
  const double det = k.low[1] * k.high[2] - k.low[2] * k.high[1];
  bool finite = std::isfinite(det) && det != 0 && std::isfinite(k.var_t);
  for (double v : k.minv) finite = finite && std::isfinite(v);
  for (double v : k.basis) finite = finite && std::isfinite(v);
  if (!finite)
    fail(
        "dual energy: the parameters are no calibration (the polynomials' linear terms cannot "
        "be inverted, or a value is not finite): calibrate the lane with `rangexctl calib "
        "dual-energy`");
}
void check_count(int pixels) {
  if (pixels < 0) fail("dual energy: a batch of " + std::to_string(pixels) + " pixels");
}
}  // namespace

void check_dual_energy_batch(const DualEnergyBatch& b, const DualEnergyParams& k) {
  check_count(b.pixels);
  if (b.pixels > 0 && (!b.low || !b.high || !b.open_low || !b.open_high || !b.thickness))
    fail("dual energy: a batch without both layers' readings, their open beams or the thickness");
  check_params(k);
}

void check_dual_energy_batch(const DualEnergyBoneBatch& b, const DualEnergyParams& k) {
  check_count(b.pixels);
  if (b.pixels > 0 && (!b.basis || !b.thickness || !b.phi || !b.phi_var))
    fail("dual energy: a bone batch without the basis, the thickness or the fat share");
  if (!(b.density_var >= 0) || !std::isfinite(b.density_var))
    fail("dual energy: the soft tissue's density variance must be finite and >= 0, not " +
         std::to_string(b.density_var));
  check_params(k);
}

namespace {
// The value and both partial derivatives of polynomial c at the powers pu, pv: one pass over
// the terms (the kernels' loop).
void evaluate(const double* c, const double* pu, const double* pv, double* f, double* du,
              double* dv) {
  double s = 0, gu = 0, gv = 0;
  int k = 0;
  for (int d = 0; d <= DE_DEGREE; ++d)
    for (int j = 0; j <= d; ++j, ++k) {
      const int i = d - j;
      s += c[k] * (pu[i] * pv[j]);
      if (i > 0) gu += c[k] * i * pu[i - 1] * pv[j];
      if (j > 0) gv += c[k] * j * pu[i] * pv[j - 1];
    }
  *f = s, *du = gu, *dv = gv;
}
}  // namespace

bool dual_energy_invert(const DualEnergyParams& k, double x, double y, double* a, double* b,
                        double jinv[4]) {
  // The linear terms' inverse starts it; at most DE_NEWTON steps, until a step is below
  // 1e-14 (of the scaled lengths: double precision).
  double det = k.low[1] * k.high[2] - k.low[2] * k.high[1];
  double u = (k.high[2] * (x - k.low[0]) - k.low[2] * (y - k.high[0])) / det;
  double v = (k.low[1] * (y - k.high[0]) - k.high[1] * (x - k.low[0])) / det;
  double pu[DE_DEGREE + 1], pv[DE_DEGREE + 1], fx = 0, fy = 0, lu = 0, lv = 0, hu = 0, hv = 0;
  for (int it = 0;; ++it) {
    powers(u, pu);
    powers(v, pv);
    evaluate(k.low, pu, pv, &fx, &lu, &lv);
    evaluate(k.high, pu, pv, &fy, &hu, &hv);
    fx -= x, fy -= y;
    det = lu * hv - lv * hu;
    if (it == DE_NEWTON) break;
    const double su = (hv * fx - lv * fy) / det, sv = (lu * fy - hu * fx) / det;
    u -= su, v -= sv;
    if (std::abs(su) < 1e-14 && std::abs(sv) < 1e-14) it = DE_NEWTON - 1;  // one last look
  }
  // d(A, B) / d(x, y), in mm, and the residual, at the last (u, v).
  jinv[0] = DE_A_MM * hv / det, jinv[1] = -DE_A_MM * lv / det;
  jinv[2] = -DE_B_MM * hu / det, jinv[3] = DE_B_MM * lu / det;
  *a = DE_A_MM * u, *b = DE_B_MM * v;
  return std::isfinite(u) && std::isfinite(v) && std::abs(fx) < 1e-6 && std::abs(fy) < 1e-6;
}

void dual_energy_basis(const DualEnergyBatch& b, const DualEnergyParams& k, float* basis) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int p = 0; p < b.pixels; ++p) {
    float* o = basis + 5 * p;
    o[0] = o[1] = o[2] = o[3] = o[4] = nan;
    const double lo = b.low[p], hi = b.high[p];
    if ((b.use && !b.use[p]) || lo <= 0 || hi <= 0 || !(b.open_low[p] > 0) || !(b.open_high[p] > 0))
      continue;
    const double x = std::log(b.open_low[p] / lo), y = std::log(b.open_high[p] / hi);
    double A, B, J[4];
    if (!dual_energy_invert(k, x, y, &A, &B, J)) continue;
    // The counts through the inverse's Jacobian, plus the calibration's own error.
    const double vx = (k.gain_low * lo + k.var_e_low) / (lo * lo),
                 vy = (k.gain_high * hi + k.var_e_high) / (hi * hi);
    o[0] = float(A), o[1] = float(B);
    o[2] = float(J[0] * J[0] * vx + J[1] * J[1] * vy + k.var_a);
    o[3] = float(J[0] * J[2] * vx + J[1] * J[3] * vy);
    o[4] = float(J[2] * J[2] * vx + J[3] * J[3] * vy + k.var_b);
  }
}

void dual_energy_lengths(const float* basis, const float* thickness, int pixels,
                         const DualEnergyParams& k, float* lengths, float* sigma) {
  const double* m = k.minv;
  for (int p = 0; p < pixels; ++p) {
    const float* in = basis + 5 * p;
    const double A = in[0], B = in[1], T = thickness[p];
    for (int r = 0; r < 3; ++r) {
      const double u = m[3 * r], v = m[3 * r + 1], w = m[3 * r + 2];
      lengths[3 * p + r] = float(u * A + v * B + w * T);
      sigma[3 * p + r] =
          float(std::sqrt(u * u * in[2] + 2 * u * v * in[3] + v * v * in[4] + w * w * k.var_t));
    }
  }
}

void dual_energy_bone(const float* basis, const float* thickness, const float* phi,
                      const float* phi_var, int pixels, const DualEnergyParams& k, float* bone,
                      float* bone_sigma, double density_var) {
  const double* L = k.basis;  // lean (a, b), fat (a, b), bone (a, b) per mm
  for (int p = 0; p < pixels; ++p) {
    const float* in = basis + 5 * p;
    const double f = phi[p], T = thickness[p];
    // The soft tissue's basis per mm, and bone's against it.
    const double sa = (1 - f) * L[0] + f * L[2], sb = (1 - f) * L[1] + f * L[3];
    const double da = L[4] - sa, db = L[5] - sb;
    const double ra = in[0] - sa * T, rb = in[1] - sb * T;
    // Covariance of (ra, rb): the pair's, the thickness's through s, phi's through
    // d s / d phi = fat - lean (per mm, times T), and the soft tissue's own density along s
    // (relative variance density_var: denser tissue is more of s, never bone).
    const double ea = (L[2] - L[0]) * T, eb = (L[3] - L[1]) * T, vp = phi_var[p];
    const double vt = k.var_t + density_var * T * T;
    const double caa = in[2] + sa * sa * vt + ea * ea * vp,
                 cab = in[3] + sa * sb * vt + ea * eb * vp,
                 cbb = in[4] + sb * sb * vt + eb * eb * vp;
    const double det = caa * cbb - cab * cab;
    // C^-1 d and the weighted sums.
    const double ia = (cbb * da - cab * db) / det, ib = (caa * db - cab * da) / det;
    const double info = da * ia + db * ib;
    bone[p] = float((ra * ia + rb * ib) / info);
    bone_sigma[p] = float(1 / std::sqrt(info));
  }
}

void dual_energy_decompose(const DualEnergyBatch& b, const DualEnergyParams& k, float* lengths,
                           float* sigma) {
  std::vector<float> basis(5 * size_t(b.pixels));
  dual_energy_basis(b, k, basis.data());
  dual_energy_lengths(basis.data(), b.thickness, b.pixels, k, lengths, sigma);
}

}  // namespace rangex
