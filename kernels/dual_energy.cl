// The dual-energy decomposition of a batch of pixels: server/pipeline/dual_energy.cpp line by
// line, one work-item a pixel, in double (no contraction: common.cl), so that each float
// result rounds as the reference's does.
//   dual_energy: low, high (DN), each layer's open beam, the laser's thickness, use per
//   pixel -> basis (A, B, var A, cov AB, var B), lengths and sigmas (lean, fat, bone);
//   dual_energy_bone: basis, thickness, the fat share phi and its variance -> bone, sigma.
#include "shared/dual_energy.h"

void de_powers(double x, double* p) {
  p[0] = 1;
  for (int i = 1; i <= DE_DEGREE; ++i) p[i] = p[i - 1] * x;
}

// The value and both partial derivatives of polynomial c at the powers pu, pv.
void de_evaluate(global const double* c, const double* pu, const double* pv, double* f, double* du,
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
  *f = s;
  *du = gu;
  *dv = gv;
}

// (A, B) in mm from (x, y) by Newton's method from the linear terms' inverse, at most
// DE_NEWTON steps, until a step is below 1e-14; false when it does not settle.
bool de_invert(global const struct DualEnergyK* k, double x, double y, double* a, double* b,
               double* jinv) {
  double det = k->low[1] * k->high[2] - k->low[2] * k->high[1];
  double u = (k->high[2] * (x - k->low[0]) - k->low[2] * (y - k->high[0])) / det;
  double v = (k->low[1] * (y - k->high[0]) - k->high[1] * (x - k->low[0])) / det;
  double pu[DE_DEGREE + 1], pv[DE_DEGREE + 1], fx = 0, fy = 0, lu = 0, lv = 0, hu = 0, hv = 0;
  for (int it = 0;; ++it) {
    de_powers(u, pu);
    de_powers(v, pv);
    de_evaluate(k->low, pu, pv, &fx, &lu, &lv);
    de_evaluate(k->high, pu, pv, &fy, &hu, &hv);
    fx -= x;
    fy -= y;
    det = lu * hv - lv * hu;
    if (it == DE_NEWTON) break;
    const double su = (hv * fx - lv * fy) / det, sv = (lu * fy - hu * fx) / det;
    u -= su;
    v -= sv;
    if (fabs(su) < 1e-14 && fabs(sv) < 1e-14) it = DE_NEWTON - 1;  // one last look
  }
  jinv[0] = DE_A_MM * hv / det;
  jinv[1] = -DE_A_MM * lv / det;
  jinv[2] = -DE_B_MM * hu / det;
  jinv[3] = DE_B_MM * lu / det;
  *a = DE_A_MM * u;
  *b = DE_B_MM * v;
  return isfinite(u) && isfinite(v) && fabs(fx) < 1e-6 && fabs(fy) < 1e-6;
}

kernel void dual_energy(global const ushort* low, global const ushort* high,
                        global const float* open_low, global const float* open_high,
                        global const float* thickness, global const uchar* use,
                        global const struct DualEnergyK* k, int pixels, global float* basis,
                        global float* lengths, global float* sigma) {
  const int p = (int)get_global_id(0);
  if (p >= pixels) return;
  float o[5] = {NAN, NAN, NAN, NAN, NAN};
  const double lo = low[p], hi = high[p];
  if (use[p] && lo > 0 && hi > 0 && open_low[p] > 0 && open_high[p] > 0) {
    const double x = log((double)open_low[p] / lo), y = log((double)open_high[p] / hi);
    double A, B, J[4];
    if (de_invert(k, x, y, &A, &B, J)) {
      // The counts through the inverse's Jacobian, plus the calibration's own error.
      const double vx = (k->gain_low * lo + k->var_e_low) / (lo * lo),
                   vy = (k->gain_high * hi + k->var_e_high) / (hi * hi);
      o[0] = (float)A;
      o[1] = (float)B;
      o[2] = (float)(J[0] * J[0] * vx + J[1] * J[1] * vy + k->var_a);
      o[3] = (float)(J[0] * J[2] * vx + J[1] * J[3] * vy);
      o[4] = (float)(J[2] * J[2] * vx + J[3] * J[3] * vy + k->var_b);
    }
  }
  for (int i = 0; i < 5; ++i) basis[5 * p + i] = o[i];
  // The three lengths from the float basis, as the reference reads it back.
  const double A = o[0], B = o[1], T = thickness[p];
  for (int r = 0; r < 3; ++r) {
    const double u = k->minv[3 * r], v = k->minv[3 * r + 1], w = k->minv[3 * r + 2];
    lengths[3 * p + r] = (float)(u * A + v * B + w * T);
    sigma[3 * p + r] = (float)sqrt(u * u * (double)o[2] + 2 * u * v * (double)o[3] +
                                   v * v * (double)o[4] + w * w * k->var_t);
  }
}

kernel void dual_energy_bone(global const float* basis, global const float* thickness,
                             global const float* phi, global const float* phi_var,
                             global const struct DualEnergyK* k, int pixels, double density_var,
                             global float* bone, global float* bone_sigma) {
  const int p = (int)get_global_id(0);
  if (p >= pixels) return;
  global const double* L = k->basis;  // lean (a, b), fat (a, b), bone (a, b) per mm
  global const float* in = basis + 5 * p;
  const double f = phi[p], T = thickness[p];
  const double sa = (1 - f) * L[0] + f * L[2], sb = (1 - f) * L[1] + f * L[3];
  const double da = L[4] - sa, db = L[5] - sb;
  const double ra = in[0] - sa * T, rb = in[1] - sb * T;
  const double ea = (L[2] - L[0]) * T, eb = (L[3] - L[1]) * T, vp = phi_var[p];
  const double vt = k->var_t + density_var * T * T;
  const double caa = in[2] + sa * sa * vt + ea * ea * vp, cab = in[3] + sa * sb * vt + ea * eb * vp,
               cbb = in[4] + sb * sb * vt + eb * eb * vp;
  const double det = caa * cbb - cab * cab;
  const double ia = (cbb * da - cab * db) / det, ib = (caa * db - cab * da) / det;
  const double info = da * ia + db * ib;
  bone[p] = (float)((ra * ia + rb * ib) / info);
  bone_sigma[p] = (float)(1 / sqrt(info));
}
