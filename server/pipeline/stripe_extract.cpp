#include "pipeline/stripe_extract.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rangex {

void StripeOutput::resize(size_t n) {
  row.assign(n, 0.f);
  peak.assign(n, 0.f);
  width.assign(n, 0.f);
  asym.assign(n, 0.f);
  centroid.assign(n, 0.f);
  valid.assign(n, 0);
}

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Pass A: running maximum and its first row for every column, streaming the frame row by
// row so that memory is read once, sequentially.
template <typename Arg>
void column_max(const uint8_t* f, int width, int height, uint8_t* mx, Arg* arg) {
  std::fill(mx, mx + width, 0);
  std::fill(arg, arg + width, 0);
  for (int r = 0; r < height; ++r) {
    const uint8_t* row = f + size_t(r) * width;
    const Arg rr = static_cast<Arg>(r);
    for (int c = 0; c < width; ++c) {
      const uint8_t v = row[c];
      const bool gt = v > mx[c];
      mx[c] = gt ? v : mx[c];
      arg[c] = gt ? rr : arg[c];
    }
  }
}

// Pass B for one column: window, sums and the method's estimate.
void column_estimate(const uint8_t* f, int width, int height, int c, int m, int p,
                     const StripeSlot& s, StripeOutput& out, size_t o) {
  auto g = [&](int y) { return float(f[size_t(y) * width + c]); };
  out.row[o] = kNaN;
  out.peak[o] = float(m);
  out.valid[o] = 0;
  if (m < s.params.min_peak) return;
  const float T = float(s.params.threshold_rel) * float(m);
  int lo = p, hi = p;
  while (lo > 0 && g(lo - 1) > T) --lo;
  while (hi < height - 1 && g(hi + 1) > T) ++hi;
  const int w = hi - lo + 1;
  out.width[o] = float(w);
  if (w > s.params.max_width) return;

  // Saturated plateau: its centre stands in for the peak of the 3-point methods.
  int pe = p;
  while (pe < hi && g(pe + 1) == float(m)) ++pe;
  double gauss_peak = 0.5 * (p + pe), parab_peak = gauss_peak;
  if (pe == p && p > 0 && p < height - 1) {
    const double a = g(p - 1), b = g(p), cc = g(p + 1);
    const double la = std::log(std::max(a, 1.0)), lb = std::log(b), lc = std::log(std::max(cc, 1.0));
    const double dg = la - 2 * lb + lc, dp = a - 2 * b + cc;
    if (dg < 0) gauss_peak = p + 0.5 * (la - lc) / dg;
    if (dp < 0) parab_peak = p + 0.5 * (a - cc) / dp;
  }

  double s0 = 0, s1 = 0, q0 = 0, q1 = 0, below = 0, above = 0;
  for (int y = lo; y <= hi; ++y) {
    const double wgt = g(y) - T;
    s0 += wgt;
    s1 += wgt * y;
    q0 += wgt * wgt;
    q1 += wgt * wgt * y;
    const double frac = std::clamp(gauss_peak - (y - 0.5), 0.0, 1.0);
    below += wgt * frac;
    above += wgt * (1 - frac);
  }
  const double C = s1 / s0;
  const double asym = (below - above) / (below + above);

  double r;
  switch (s.params.method) {
    case StripeMethod::kCentroid: r = C; break;
    case StripeMethod::kSquared: r = q1 / q0; break;
    case StripeMethod::kBinary: {
      const double th = 0.5 * m;
      int l = p, h = p;
      while (l > 0 && g(l - 1) > th) --l;
      while (h < height - 1 && g(h + 1) > th) ++h;
      const double left = l > 0 ? (l - 1) + (th - g(l - 1)) / (g(l) - g(l - 1)) : l - 0.5;
      const double right = h < height - 1 ? h + (g(h) - th) / (g(h) - g(h + 1)) : h + 0.5;
      r = 0.5 * (left + right);
      break;
    }
    case StripeMethod::kGaussian3: r = gauss_peak; break;
    case StripeMethod::kParabola: r = parab_peak; break;
    case StripeMethod::kShifted: r = C + s.scatter.k1; break;
    case StripeMethod::kModified:
    default: r = C + s.scatter.k2_offset + s.scatter.k2 * asym; break;
  }
  out.row[o] = float(r);
  out.asym[o] = float(asym);
  out.centroid[o] = float(C);
  out.valid[o] = 1;
}

}  // namespace

void extract_stripes(const uint8_t* frames, int count, int width, int height, const int* slot,
                     const StripeSlot* slots, StripeOutput& out) {
  out.resize(size_t(count) * width);
  std::vector<uint8_t> mx(width);
  std::vector<uint16_t> arg16(width);
  std::vector<uint8_t> arg8(width);
  const size_t frame = size_t(width) * height;
  for (int i = 0; i < count; ++i) {
    const uint8_t* f = frames + frame * i;
    const StripeSlot& s = slots[slot[i]];
    // Rows fit a byte for the usual sensor heights, which keeps pass A in 8-bit lanes.
    if (height <= 256) column_max(f, width, height, mx.data(), arg8.data());
    else column_max(f, width, height, mx.data(), arg16.data());
    for (int c = 0; c < width; ++c) {
      const int p = height <= 256 ? arg8[c] : arg16[c];
      column_estimate(f, width, height, c, mx[c], p, s, out, size_t(i) * width + c);
    }
  }
}

}  // namespace rangex
