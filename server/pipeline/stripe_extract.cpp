#include "pipeline/stripe_extract.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/stripe_column.h"

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

// Running maximum and its first row for every column, streaming the frame row by row so
// that memory is read once, sequentially.
// Kept out of line: inlined into the caller, GCC schedules the loop worse (measured: twice
// the time per frame).
template <typename Arg>
__attribute__((noinline)) void column_max(const uint8_t* __restrict f, int width, int height,
                                          uint8_t* __restrict mx, Arg* __restrict arg) {
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

// The connected run above T around p, and the end of the saturated plateau starting at p.
inline void window(const uint8_t* f, int width, int height, int c, int p, int m, float T, int& lo,
                   int& hi, int& pe) {
  auto g = [&](int y) { return float(f[size_t(y) * width + c]); };
  lo = hi = pe = p;
  while (lo > 0 && g(lo - 1) > T) --lo;
  while (hi < height - 1 && g(hi + 1) > T) ++hi;
  while (pe < hi && f[size_t(pe + 1) * width + c] == m) ++pe;
}

inline int at(const uint8_t* f, int width, int height, int c, int y) {
  return f[size_t(std::clamp(y, 0, height - 1)) * width + c];
}

struct Scratch {
  std::vector<uint8_t> mx, arg8;
  std::vector<uint16_t> arg16;
  std::vector<int> lo, hi, p, pe;
  std::vector<float> T, gauss, parab;
  std::vector<float> s0, s1, q0, q1, below;  // window sums, one lane per column
  std::vector<int> lo_in, hi_in;             // window bounds, empty when invalid
  void resize(int w) {
    mx.resize(w);
    arg8.resize(w);
    arg16.resize(w);
    lo.resize(w);
    hi.resize(w);
    p.resize(w);
    pe.resize(w);
    T.resize(w);
    gauss.resize(w);
    parab.resize(w);
    for (auto* v : {&s0, &s1, &q0, &q1, &below}) v->resize(w);
    lo_in.resize(w);
    hi_in.resize(w);
  }
};

// stripe::accumulate for one pixel, over the flat per-column arrays.
inline void sum_pixel(Scratch& s, int c, int r, float g) {
  const float w = g - s.T[c], y = float(r);
  const float frac = std::clamp(s.gauss[c] - (y - 0.5f), 0.0f, 1.0f);
  s.s0[c] += w;
  s.s1[c] += w * y;
  s.q0[c] += w * w;
  s.q1[c] += w * w * y;
  s.below[c] += w * frac;
}

// The window sums of N neighbouring columns: rows r0..r1 cover every window in the group;
// with N fixed the per-column state stays in vector registers across the rows.
template <int N>
void sum_group(const uint8_t* f, int width, int r0, int r1, int c0, Scratch& s) {
  int lo[N], hi[N];
  float T[N], gp[N], s0[N] = {}, s1[N] = {}, q0[N] = {}, q1[N] = {}, bl[N] = {};
  for (int k = 0; k < N; ++k) {
    lo[k] = s.lo_in[c0 + k];
    hi[k] = s.hi_in[c0 + k];
    T[k] = s.T[c0 + k];
    gp[k] = s.gauss[c0 + k];
  }
  for (int r = r0; r <= r1; ++r) {
    const uint8_t* row = f + size_t(r) * width + c0;
    const float y = float(r);
    for (int k = 0; k < N; ++k) {
      // Branch-free so that the compiler keeps the loop in vector lanes.
      const float in = float((r >= lo[k]) & (r <= hi[k]));
      const float w = in * (float(row[k]) - T[k]);
      const float frac = std::min(std::max(gp[k] - (y - 0.5f), 0.0f), 1.0f);
      s0[k] += w;
      s1[k] += w * y;
      q0[k] += w * w;
      q1[k] += w * w * y;
      bl[k] += w * frac;
    }
  }
  for (int k = 0; k < N; ++k) {
    s.s0[c0 + k] = s0[k];
    s.s1[c0 + k] = s1[k];
    s.q0[c0 + k] = q0[k];
    s.q1[c0 + k] = q1[k];
    s.below[c0 + k] = bl[k];
  }
}

// Window bounds of N neighbouring columns found row by row instead of column by column:
// walking away from the peaks, each lane stays connected while its pixels exceed its
// threshold; the walk stops once every lane has left its window (or passed max_width).
template <int N>
void window_group(const uint8_t* f, int width, int height, int c0, int max_width, Scratch& s) {
  int p[N], lo[N], hi[N], live[N];
  float T[N];
  int pmin = height, pmax = -1;
  for (int k = 0; k < N; ++k) {
    p[k] = s.p[c0 + k];
    T[k] = s.T[c0 + k];
    lo[k] = hi[k] = p[k];
    const bool valid = s.lo[c0 + k] >= 0;
    if (valid) pmin = std::min(pmin, p[k]), pmax = std::max(pmax, p[k]);
  }
  if (pmax < 0) return;
  for (int k = 0; k < N; ++k) live[k] = 1;
  for (int r = pmin + 1; r < height && r <= pmax + max_width; ++r) {
    const uint8_t* row = f + size_t(r) * width + c0;
    int any = 0;
    for (int k = 0; k < N; ++k) {
      const int beyond = r > p[k];
      const int above = float(row[k]) > T[k];
      const int grow = live[k] & beyond & above;
      hi[k] = grow ? r : hi[k];
      live[k] = live[k] & (!beyond | above);
      any |= live[k];
    }
    if (!any) break;
  }
  for (int k = 0; k < N; ++k) live[k] = 1;
  for (int r = pmax - 1; r >= 0 && r >= pmin - max_width; --r) {
    const uint8_t* row = f + size_t(r) * width + c0;
    int any = 0;
    for (int k = 0; k < N; ++k) {
      const int beyond = r < p[k];
      const int above = float(row[k]) > T[k];
      const int grow = live[k] & beyond & above;
      lo[k] = grow ? r : lo[k];
      live[k] = live[k] & (!beyond | above);
      any |= live[k];
    }
    if (!any) break;
  }
  for (int k = 0; k < N; ++k)
    if (s.lo[c0 + k] >= 0) {
      s.lo[c0 + k] = lo[k];
      s.hi[c0 + k] = hi[k];
    }
}

void peaks(const uint8_t* f, int width, int height, Scratch& s) {
  // Rows fit a byte for the usual sensor heights, which keeps the scan in 8-bit lanes.
  if (height <= 256) {
    column_max(f, width, height, s.mx.data(), s.arg8.data());
    for (int c = 0; c < width; ++c) s.p[c] = s.arg8[c];
  } else {
    column_max(f, width, height, s.mx.data(), s.arg16.data());
    for (int c = 0; c < width; ++c) s.p[c] = s.arg16[c];
  }
}

// Everything after the sums: validity, the method's row, outputs.
void finish(const uint8_t* f, int width, int height, const StripeSlot& sl, const Scratch& s,
            StripeOutput& out, size_t o0) {
  for (int c = 0; c < width; ++c) {
    const size_t o = o0 + c;
    const int m = s.mx[c];
    out.peak[o] = float(m);
    out.row[o] = kNaN;
    out.valid[o] = 0;
    if (s.lo[c] < 0) continue;  // no stripe
    const int w = s.hi[c] - s.lo[c] + 1;
    out.width[o] = float(w);
    if (w > sl.params.max_width) continue;
    const float binary = sl.params.method == StripeMethod::kBinary
                             ? stripe::half_max_midpoint(f, width, height, c, m, s.p[c])
                             : 0.f;
    float centroid, asym;
    const stripe::Sums sums{s.s0[c], s.s1[c], s.q0[c], s.q1[c], s.below[c]};
    out.row[o] = stripe::method_row(sl.params.method, sums, {s.gauss[c], s.parab[c]}, binary,
                                    sl.scatter, centroid, asym);
    out.centroid[o] = centroid;
    out.asym[o] = asym;
    out.valid[o] = 1;
  }
}

}  // namespace

void extract_stripes(const uint8_t* frames, int count, int width, int height, const int* slot,
                     const StripeSlot* slots, StripeOutput& out) {
  out.resize(size_t(count) * width);
  Scratch s;
  s.resize(width);
  const size_t frame = size_t(width) * height;
  constexpr int kGroup = 16;  // neighbouring columns whose windows are summed together
  for (int i = 0; i < count; ++i) {
    const uint8_t* f = frames + frame * i;
    const StripeSlot& sl = slots[slot[i]];
    peaks(f, width, height, s);
    for (int c = 0; c < width; ++c) {
      s.s0[c] = s.s1[c] = s.q0[c] = s.q1[c] = s.below[c] = 0;
      s.lo_in[c] = 1, s.hi_in[c] = 0;  // empty unless the window is valid
      s.T[c] = float(sl.params.threshold_rel) * float(s.mx[c]);
      s.gauss[c] = 0;
      s.lo[c] = s.hi[c] = s.mx[c] < sl.params.min_peak ? -1 : s.p[c];
    }
    for (int c0 = 0; c0 < width; c0 += kGroup) {
      if (c0 + kGroup <= width) {
        window_group<kGroup>(f, width, height, c0, sl.params.max_width, s);
      } else {
        for (int c = c0; c < width; ++c)  // ragged last group
          if (s.lo[c] >= 0) window(f, width, height, c, s.p[c], s.mx[c], s.T[c], s.lo[c], s.hi[c], s.pe[c]);
      }
    }
    for (int c = 0; c < width; ++c) {
      if (s.lo[c] < 0) continue;
      const int m = s.mx[c], p = s.p[c];
      int pe = p;
      if (m == 255)  // saturated: find the end of the plateau
        while (pe < s.hi[c] && f[size_t(pe + 1) * width + c] == m) ++pe;
      const stripe::Peaks k = stripe::three_point_peaks(at(f, width, height, c, p - 1), m,
                                                        at(f, width, height, c, p + 1), p, pe);
      s.gauss[c] = k.gauss;
      s.parab[c] = k.parab;
      if (s.hi[c] - s.lo[c] < sl.params.max_width) s.lo_in[c] = s.lo[c], s.hi_in[c] = s.hi[c];
    }
    // Window sums: for a group of columns, the band of rows that any of their windows
    // covers, walked row by row; the inner loop runs across columns and vectorises.
    for (int c0 = 0; c0 < width; c0 += kGroup) {
      const int c1 = std::min(width, c0 + kGroup);
      int r0 = height, r1 = -1;
      for (int c = c0; c < c1; ++c)
        if (s.lo_in[c] <= s.hi_in[c]) {
          r0 = std::min(r0, s.lo_in[c]);
          r1 = std::max(r1, s.hi_in[c]);
        }
      if (c1 - c0 == kGroup) {
        sum_group<kGroup>(f, width, r0, r1, c0, s);
      } else {
        for (int c = c0; c < c1; ++c)  // ragged last group
          for (int r = s.lo_in[c]; r <= s.hi_in[c]; ++r)
            sum_pixel(s, c, r, float(f[size_t(r) * width + c]));
      }
    }
    finish(f, width, height, sl, s, out, size_t(i) * width);
  }
}

void extract_stripes_reference(const uint8_t* frames, int count, int width, int height,
                               const int* slot, const StripeSlot* slots, StripeOutput& out) {
  out.resize(size_t(count) * width);
  const size_t frame = size_t(width) * height;
  // One "work-item" per (frame, column): everything below reads only that column.
  for (int i = 0; i < count; ++i)
    for (int c = 0; c < width; ++c) {
      const uint8_t* f = frames + frame * i;
      const StripeSlot& sl = slots[slot[i]];
      const size_t o = size_t(i) * width + c;
      int m = 0, p = 0;
      for (int r = 0; r < height; ++r) {
        const int v = f[size_t(r) * width + c];
        if (v > m) m = v, p = r;
      }
      out.peak[o] = float(m);
      out.row[o] = kNaN;
      out.valid[o] = 0;
      if (m < sl.params.min_peak) continue;
      const float T = float(sl.params.threshold_rel) * float(m);
      int lo, hi, pe;
      window(f, width, height, c, p, m, T, lo, hi, pe);
      out.width[o] = float(hi - lo + 1);
      if (hi - lo + 1 > sl.params.max_width) continue;
      const stripe::Peaks k = stripe::three_point_peaks(at(f, width, height, c, p - 1), m,
                                                        at(f, width, height, c, p + 1), p, pe);
      stripe::Sums sums;
      for (int y = lo; y <= hi; ++y)
        stripe::accumulate(sums, float(f[size_t(y) * width + c]) - T, float(y), k.gauss);
      const float binary = sl.params.method == StripeMethod::kBinary
                               ? stripe::half_max_midpoint(f, width, height, c, m, p)
                               : 0.f;
      float centroid, asym;
      out.row[o] = stripe::method_row(sl.params.method, sums, k, binary, sl.scatter, centroid, asym);
      out.centroid[o] = centroid;
      out.asym[o] = asym;
      out.valid[o] = 1;
    }
}

}  // namespace rangex
