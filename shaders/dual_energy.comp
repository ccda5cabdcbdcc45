#version 450
// The dual-energy decomposition of a batch of pixels: kernels/dual_energy.cl (dual_energy)
// for Vulkan, one invocation a pixel, in double. GLSL has no double log: ln_d below gives it
// to a few units in the last place. DN and use flags are read from 32-bit words.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "shared/dual_energy.h"

layout(local_size_x = 64) in;
// Its buffer blocks one a line (clang-format takes them for classes).
// clang-format off
layout(std430, binding = 0) readonly buffer Low { uint low_words[]; };
layout(std430, binding = 1) readonly buffer High { uint high_words[]; };
layout(std430, binding = 2) readonly buffer OpenLow { float open_low[]; };
layout(std430, binding = 3) readonly buffer OpenHigh { float open_high[]; };
layout(std430, binding = 4) readonly buffer Thickness { float thickness[]; };
layout(std430, binding = 5) readonly buffer Use { uint use_words[]; };
layout(std430, binding = 6) readonly buffer Params { DualEnergyK k; };
layout(std430, binding = 7) writeonly buffer Basis { float basis[]; };
layout(std430, binding = 8) writeonly buffer Lengths { float lengths[]; };
layout(std430, binding = 9) writeonly buffer Sigma { float sigma[]; };
layout(push_constant) uniform Push { DualEnergyPush pc; };
// clang-format on

uint low_at(int i) {
  return (low_words[i >> 1] >> (16 * (i & 1))) & 0xffffu;
}
uint high_at(int i) {
  return (high_words[i >> 1] >> (16 * (i & 1))) & 0xffffu;
}
bool use_at(int i) {
  return ((use_words[i >> 2] >> (8 * (i & 3))) & 0xffu) != 0u;
}

// ln x for x > 0: x = m 2^e with m in [sqrt(1/2), sqrt(2)), ln m = 2 atanh(s), s = (m - 1) /
// (m + 1), |s| < 0.172, by its series to s^25 (the next term is below 1e-18).
double ln_d(double x) {
  int e;
  precise double m = frexp(x, e);
  if (m < 0.70710678118654752lf) {
    m *= 2.0lf;
    e -= 1;
  }
  precise const double s = (m - 1.0lf) / (m + 1.0lf), z = s * s;
  precise double sum = 0.0lf;
  for (int n = 12; n >= 0; --n) sum = sum * z + 1.0lf / double(2 * n + 1);
  return double(e) * 0.69314718055994530942lf + 2.0lf * s * sum;
}

double pu[DE_DEGREE + 1], pv[DE_DEGREE + 1];

void set_powers(double u, double v) {
  pu[0] = 1.0lf;
  pv[0] = 1.0lf;
  for (int i = 1; i <= DE_DEGREE; ++i) {
    pu[i] = pu[i - 1] * u;
    pv[i] = pv[i - 1] * v;
  }
}

// The low (layer 0) or high (layer 1) polynomial's value and partial derivatives at the
// powers set: (f, df/du, df/dv).
dvec3 evaluate(int layer) {
  precise double s = 0.0lf, gu = 0.0lf, gv = 0.0lf;
  int k2 = 0;
  for (int d = 0; d <= DE_DEGREE; ++d)
    for (int j = 0; j <= d; ++j, ++k2) {
      const int i = d - j;
      const double c = layer == 0 ? k.low[k2] : k.high[k2];
      s += c * (pu[i] * pv[j]);
      if (i > 0) gu += c * double(i) * pu[i - 1] * pv[j];
      if (j > 0) gv += c * double(j) * pu[i] * pv[j - 1];
    }
  return dvec3(s, gu, gv);
}

void main() {
  const int p = int(gl_GlobalInvocationID.x);
  if (p >= pc.pixels) return;
  float o[5] = float[5](kNaN, kNaN, kNaN, kNaN, kNaN);
  const double lo = double(low_at(p)), hi = double(high_at(p));
  if (use_at(p) && lo > 0.0lf && hi > 0.0lf && open_low[p] > 0.0 && open_high[p] > 0.0) {
    precise const double x = ln_d(double(open_low[p]) / lo), y = ln_d(double(open_high[p]) / hi);
    // Newton's method from the linear terms' inverse, at most DE_NEWTON steps, until a step is
    // below 1e-14 (pipeline/dual_energy.cpp).
    precise double det = k.low[1] * k.high[2] - k.low[2] * k.high[1];
    precise double u = (k.high[2] * (x - k.low[0]) - k.low[2] * (y - k.high[0])) / det;
    precise double v = (k.low[1] * (y - k.high[0]) - k.high[1] * (x - k.low[0])) / det;
    dvec3 l, h;
    for (int it = 0;; ++it) {
      set_powers(u, v);
      l = evaluate(0);
      h = evaluate(1);
      l.x -= x;
      h.x -= y;
      det = l.y * h.z - l.z * h.y;
      if (it == DE_NEWTON) break;
      precise const double su = (h.z * l.x - l.z * h.x) / det, sv = (l.y * h.x - h.y * l.x) / det;
      u -= su;
      v -= sv;
      if (abs(su) < 1e-14lf && abs(sv) < 1e-14lf) it = DE_NEWTON - 1;  // one last look
    }
    precise const double j0 = DE_A_MM * h.z / det, j1 = -DE_A_MM * l.z / det;
    precise const double j2 = -DE_B_MM * h.y / det, j3 = DE_B_MM * l.y / det;
    const bool ok =
        !isnan(u) && !isinf(u) && !isnan(v) && !isinf(v) && abs(l.x) < 1e-6lf && abs(h.x) < 1e-6lf;
    if (ok) {
      // The counts through the inverse's Jacobian, plus the calibration's own error.
      precise const double vx = (k.gain_low * lo + k.var_e_low) / (lo * lo);
      precise const double vy = (k.gain_high * hi + k.var_e_high) / (hi * hi);
      o[0] = float(DE_A_MM * u);
      o[1] = float(DE_B_MM * v);
      o[2] = float(j0 * j0 * vx + j1 * j1 * vy + k.var_a);
      o[3] = float(j0 * j2 * vx + j1 * j3 * vy);
      o[4] = float(j2 * j2 * vx + j3 * j3 * vy + k.var_b);
    }
  }
  for (int i = 0; i < 5; ++i) basis[5 * p + i] = o[i];
  // The three lengths from the float basis, as the reference reads it back.
  const double A = double(o[0]), B = double(o[1]), T = double(thickness[p]);
  for (int r = 0; r < 3; ++r) {
    const double u = k.minv[3 * r], v = k.minv[3 * r + 1], w = k.minv[3 * r + 2];
    precise const double len = u * A + v * B + w * T;
    precise const double var = u * u * double(o[2]) + 2.0lf * u * v * double(o[3]) +
                               v * v * double(o[4]) + w * w * k.var_t;
    lengths[3 * p + r] = float(len);
    sigma[3 * p + r] = float(sqrt(var));
  }
}
