// The per-column arithmetic shared by the reference and the row-wise stripe extractors:
// the 3-point peaks, and the final row of each method from the window sums.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/stripe_params.h"

namespace rangex::stripe {

// Natural log of 8-bit intensities (0 maps to ln 1): the 3-point Gaussian needs three per
// column, and a table keeps them off the hot path.
struct LnTable {
  float v[256];
  LnTable() {
    for (int i = 0; i < 256; ++i) v[i] = std::log(float(std::max(i, 1)));
  }
};
inline const LnTable& ln_table() {
  static const LnTable t;
  return t;
}

// Last row of the flat top that starts at the peak p of column c (rows equal to the maximum
// m, e.g. saturation), not beyond the window's last row hi. The reference and both CPU
// paths call this, so that they agree on where a plateau ends.
inline int plateau_end(const uint8_t* f, int width, int c, int p, int hi, int m) {
  int pe = p;
  while (pe < hi && f[size_t(pe + 1) * width + c] == m) ++pe;
  return pe;
}

struct Peaks {
  float gauss;  // vertex of the parabola through ln g at p-1, p, p+1
  float parab;  // vertex of the parabola through g
};

// p: first row of the maximum, pe: last row of its plateau (pe > p only when saturated).
inline Peaks three_point_peaks(int a, int b, int c, int p, int pe) {
  Peaks k{0.5f * float(p + pe), 0.5f * float(p + pe)};
  if (pe != p) return k;
  const LnTable& ln = ln_table();
  const float la = ln.v[a], lb = ln.v[b], lc = ln.v[c];
  const float dg = la - 2 * lb + lc, dp = float(a - 2 * b + c);
  if (dg < 0) k.gauss = float(p) + 0.5f * (la - lc) / dg;
  if (dp < 0) k.parab = float(p) + 0.5f * float(a - c) / dp;
  return k;
}

// Window sums over rows lo..hi with weights w = g - T.
struct Sums {
  float s0 = 0, s1 = 0;  // sum w, sum w*y
  float q0 = 0, q1 = 0;  // sum w^2, sum w^2*y
  float below = 0;       // sum w * (fraction of the pixel below the Gaussian peak)
};

// Adds row y of the window; frac_below = clamp(gauss - (y - 0.5), 0, 1).
inline void accumulate(Sums& s, float w, float y, float gauss) {
  const float frac = std::clamp(gauss - (y - 0.5f), 0.0f, 1.0f);
  s.s0 += w;
  s.s1 += w * y;
  s.q0 += w * w;
  s.q1 += w * w * y;
  s.below += w * frac;
}

// The method's row; `binary` is the half-maximum midpoint (only read for kBinary).
inline float method_row(StripeMethod m, const Sums& s, const Peaks& k, float binary,
                        const ScatterConstants& sc, float& centroid, float& asym) {
  centroid = s.s1 / s.s0;
  asym = (2 * s.below - s.s0) / s.s0;  // (L - U) / (L + U)
  switch (m) {
    case StripeMethod::kCentroid:
      return centroid;
    case StripeMethod::kSquared:
      return s.q1 / s.q0;
    case StripeMethod::kBinary:
      return binary;
    case StripeMethod::kGaussian3:
      return k.gauss;
    case StripeMethod::kParabola:
      return k.parab;
    case StripeMethod::kShifted:
      return centroid + float(sc.k1);
    case StripeMethod::kModified:
    default:
      return centroid + float(sc.k2_offset) + float(sc.k2) * asym;
  }
}

// Midpoint of the interpolated half-maximum crossings around the peak p of column c.
inline float half_max_midpoint(const uint8_t* f, int width, int height, int c, int m, int p) {
  auto g = [&](int y) { return float(f[size_t(y) * width + c]); };
  const float th = 0.5f * float(m);
  int l = p, h = p;
  while (l > 0 && g(l - 1) > th) --l;
  while (h < height - 1 && g(h + 1) > th) ++h;
  const float left = l > 0 ? float(l - 1) + (th - g(l - 1)) / (g(l) - g(l - 1)) : float(l) - 0.5f;
  const float right = h < height - 1 ? float(h) + (g(h) - th) / (g(h) - g(h + 1)) : float(h) + 0.5f;
  return 0.5f * (left + right);
}

}  // namespace rangex::stripe
