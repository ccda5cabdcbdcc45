#include "pipeline/stripe_extract.h"

#include <algorithm>
#include <cmath>
#include <functional>
#if defined(__AVX512BW__) || defined(__AVX2__)
#include <immintrin.h>
#endif
#include <thread>

#include "core/no_value.h"
#include "pipeline/stripe_block64.h"
#include "pipeline/stripe_column.h"
#include "pipeline/stripe_prefetch.h"

namespace rangex {

void StripeOutput::resize(size_t n) {
  // No fill: both extractors write every field of every column, and filling would double
  // the output's memory traffic.
  row.resize(n);
  peak.resize(n);
  width.resize(n);
  asym.resize(n);
  centroid.resize(n);
  valid.resize(n);
}

namespace {

constexpr size_t kOutputBytesPerColumn = 5 * sizeof(float) + 1;  // StripeOutput's fields
constexpr size_t kStreamOutputBytes = size_t(4) << 20;           // beyond this, stream them

// Running maximum and its first row for every column, streaming the frame row by row so
// that memory is read once, sequentially.
// Kept out of line: inlined into the caller, GCC schedules the loop worse (measured: twice
// the time per frame).
// `width` columns of rows `stride` bytes apart.
template <typename Arg>
__attribute__((noinline)) void column_max(const uint8_t* __restrict f, int stride, int width,
                                          int height, uint8_t* __restrict mx, Arg* __restrict arg) {
  std::fill(mx, mx + width, 0);
  std::fill(arg, arg + width, 0);
  for (int r = 0; r < height; ++r) {
    const uint8_t* row = f + size_t(r) * stride;
    const Arg rr = static_cast<Arg>(r);
    for (int c = 0; c < width; ++c) {
      const uint8_t v = row[c];
      const bool gt = v > mx[c];
      mx[c] = gt ? v : mx[c];
      arg[c] = gt ? rr : arg[c];
    }
  }
}

#if defined(__AVX512BW__)
// The same scan with the running maximum and its row held in vector registers for a block
// of K x 64 columns (up to 640): no per-row loads and stores of the state, so the scan runs
// at the speed of reading the frame (measured 5-6 us per 640x200 frame against 7.5-8).
template <int K>
void column_max_registers(const uint8_t* __restrict f, int width, int height, int c0,
                          uint8_t* __restrict mx, uint8_t* __restrict arg) {
  __m512i m[K], a[K];
  for (int j = 0; j < K; ++j) m[j] = a[j] = _mm512_setzero_si512();
  for (int r = 0; r < height; ++r) {
    const uint8_t* row = f + size_t(r) * width + c0;
    const __m512i rv = _mm512_set1_epi8(char(r));
#pragma GCC unroll 16
    for (int j = 0; j < K; ++j) {
      const __m512i v = _mm512_loadu_si512(row + 64 * j);
      const __mmask64 gt = _mm512_cmpgt_epu8_mask(v, m[j]);  // first maximum wins
      m[j] = _mm512_max_epu8(m[j], v);
      a[j] = _mm512_mask_mov_epi8(a[j], gt, rv);
    }
  }
  for (int j = 0; j < K; ++j) {
    _mm512_storeu_si512(mx + c0 + 64 * j, m[j]);
    _mm512_storeu_si512(arg + c0 + 64 * j, a[j]);
  }
}

template <int K>
bool column_max_blocks(const uint8_t* f, int width, int height, int c0, int chunks, uint8_t* mx,
                       uint8_t* arg) {
  if constexpr (K == 0) {
    return chunks == 0;
  } else {
    if (chunks != K) return column_max_blocks<K - 1>(f, width, height, c0, chunks, mx, arg);
    column_max_registers<K>(f, width, height, c0, mx, arg);
    return true;
  }
}
#endif

// Column maxima and their first rows for frames of at most 256 rows.
void column_max8(const uint8_t* f, int width, int height, uint8_t* mx, uint8_t* arg) {
#if defined(__AVX512BW__)
  int c0 = 0;
  for (; c0 + 640 <= width; c0 += 640) column_max_registers<10>(f, width, height, c0, mx, arg);
  const int chunks = (width - c0) / 64;
  column_max_blocks<9>(f, width, height, c0, chunks, mx, arg);
  c0 += 64 * chunks;
  // The last columns (fewer than 64): the portable scan over just those columns.
  if (c0 < width) column_max(f + c0, width, width - c0, height, mx + c0, arg + c0);
#else
  column_max(f, width, width, height, mx, arg);
#endif
}

// The connected run above T around p, and the end of the flat top starting at p.
inline void window(const uint8_t* f, int width, int height, int c, int p, int m, float T, int& lo,
                   int& hi, int& pe) {
  auto g = [&](int y) { return float(f[size_t(y) * width + c]); };
  lo = hi = p;
  while (lo > 0 && g(lo - 1) > T) --lo;
  while (hi < height - 1 && g(hi + 1) > T) ++hi;
  pe = stripe::plateau_end(f, width, c, p, hi, m);
}

inline int at(const uint8_t* f, int width, int height, int c, int y) {
  return f[size_t(std::clamp(y, 0, height - 1)) * width + c];
}

// All stages after the column maxima for N neighbouring columns at once. Every loop runs
// across the N lanes with fixed trip count and no branches, so that the compiler keeps the
// per-column state in vector registers; rows are walked only where some window lies.
template <int N>
void column_group(const uint8_t* f, int width, int height, int c0, const uint8_t* mx,
                  const int* peak_row, const StripeSlot& sl, StripeOutput& out, size_t o0) {
  const float rel = float(sl.params.threshold_rel);
  const int max_width = sl.params.max_width;
  int p[N], lo[N], hi[N], live[N], valid[N];
  float m[N], T[N], a[N], c[N];
  int pmin = height, pmax = -1;
  for (int k = 0; k < N; ++k) {
    p[k] = peak_row[c0 + k];
    m[k] = float(mx[c0 + k]);
    T[k] = rel * m[k];
    valid[k] = mx[c0 + k] >= sl.params.min_peak;
    lo[k] = hi[k] = p[k];
    a[k] = c[k] = m[k];  // the 3-point neighbours, clamped at the frame's edge
  }
  for (int k = 0; k < N; ++k)
    if (valid[k]) pmin = std::min(pmin, p[k]), pmax = std::max(pmax, p[k]);

  if (pmax >= 0) {
    // Window bounds: walking away from the peaks, a lane stays connected while its pixels
    // exceed its threshold; the walk ends when every lane has left its window.
    for (int k = 0; k < N; ++k) live[k] = valid[k];
    for (int r = pmin + 1; r < height; ++r) {
      const uint8_t* row = f + size_t(r) * width + c0;
      int any = 0;
      for (int k = 0; k < N; ++k) {
        const int beyond = r > p[k], above = float(row[k]) > T[k];
        hi[k] = (live[k] & beyond & above) ? r : hi[k];
        c[k] = r == p[k] + 1 ? float(row[k]) : c[k];
        live[k] &= (!beyond) | above;
        any |= live[k];
      }
      if (!any) break;
    }
    for (int k = 0; k < N; ++k) live[k] = valid[k];
    for (int r = pmax - 1; r >= 0; --r) {
      const uint8_t* row = f + size_t(r) * width + c0;
      int any = 0;
      for (int k = 0; k < N; ++k) {
        const int beyond = r<p[k], above = float(row[k])> T[k];
        lo[k] = (live[k] & beyond & above) ? r : lo[k];
        a[k] = r == p[k] - 1 ? float(row[k]) : a[k];
        live[k] &= (!beyond) | above;
        any |= live[k];
      }
      if (!any) break;
    }
  }

  // 3-point peaks; a flat top (the next row equals the maximum, e.g. saturation) peaks at
  // the middle of its plateau, found column by column.
  float gauss[N], parab[N];
  const stripe::LnTable& ln = stripe::ln_table();
  for (int k = 0; k < N; ++k) {
    const float la = ln.v[int(a[k])], lb = ln.v[int(m[k])], lc = ln.v[int(c[k])];
    const float dg = la - 2 * lb + lc, dp = a[k] - 2 * m[k] + c[k];
    gauss[k] = dg < 0 ? float(p[k]) + 0.5f * (la - lc) / dg : float(p[k]);
    parab[k] = dp < 0 ? float(p[k]) + 0.5f * (a[k] - c[k]) / dp : float(p[k]);
  }
  for (int k = 0; k < N; ++k)
    if (valid[k] && c[k] == m[k]) {
      const int pe = stripe::plateau_end(f, width, c0 + k, p[k], hi[k], mx[c0 + k]);
      if (pe != p[k]) gauss[k] = parab[k] = 0.5f * float(p[k] + pe);
    }

  // Window sums over the band of rows that holds every valid window of the group.
  int r0 = height, r1 = -1, span[N];
  for (int k = 0; k < N; ++k) {
    span[k] = valid[k] ? hi[k] - lo[k] + 1 : 0;  // reported also for glare
    valid[k] &= hi[k] - lo[k] < max_width;
    if (!valid[k]) lo[k] = 1, hi[k] = 0;  // empty window
  }
  for (int k = 0; k < N; ++k)
    if (lo[k] <= hi[k]) r0 = std::min(r0, lo[k]), r1 = std::max(r1, hi[k]);
  float s0[N] = {}, s1[N] = {}, q0[N] = {}, q1[N] = {}, bl[N] = {};
  for (int r = r0; r <= r1; ++r) {
    const uint8_t* row = f + size_t(r) * width + c0;
    const float y = float(r);
    for (int k = 0; k < N; ++k) {
      // stripe::accumulate, spelled out over the lanes.
      const float in = float((r >= lo[k]) & (r <= hi[k]));
      const float w = in * (float(row[k]) - T[k]);
      const float frac = std::min(std::max(gauss[k] - (y - 0.5f), 0.0f), 1.0f);
      s0[k] += w;
      s1[k] += w * y;
      q0[k] += w * w;
      q1[k] += w * w * y;
      bl[k] += w * frac;
    }
  }

  // The method's row, lane by lane: stripe::method_row with the method chosen once per
  // group instead of once per column, so that each case runs vectorised.
  float C[N], A[N], R[N];
  for (int k = 0; k < N; ++k) {
    C[k] = s1[k] / s0[k];
    A[k] = (2 * bl[k] - s0[k]) / s0[k];  // (L - U) / (L + U)
  }
  const ScatterConstants& sc = sl.scatter;
  switch (sl.params.method) {
    case StripeMethod::kCentroid:
      for (int k = 0; k < N; ++k) R[k] = C[k];
      break;
    case StripeMethod::kSquared:
      for (int k = 0; k < N; ++k) R[k] = q1[k] / q0[k];
      break;
    case StripeMethod::kBinary:
      for (int k = 0; k < N; ++k)
        R[k] =
            valid[k] ? stripe::half_max_midpoint(f, width, height, c0 + k, int(m[k]), p[k]) : 0.f;
      break;
    case StripeMethod::kGaussian3:
      for (int k = 0; k < N; ++k) R[k] = gauss[k];
      break;
    case StripeMethod::kParabola:
      for (int k = 0; k < N; ++k) R[k] = parab[k];
      break;
    case StripeMethod::kShifted:
      for (int k = 0; k < N; ++k) R[k] = C[k] + float(sc.k1);
      break;
    case StripeMethod::kModified:
    default:
      for (int k = 0; k < N; ++k) R[k] = C[k] + float(sc.k2_offset) + float(sc.k2) * A[k];
      break;
  }
  const size_t o = o0 + c0;
  for (int k = 0; k < N; ++k) {
    out.row[o + k] = valid[k] ? R[k] : kNaN;
    out.peak[o + k] = m[k];
    out.width[o + k] = float(span[k]);
    out.centroid[o + k] = valid[k] ? C[k] : 0.f;
    out.asym[o + k] = valid[k] ? A[k] : 0.f;
    out.valid[o + k] = uint8_t(valid[k]);
  }
}

}  // namespace

namespace {

// Frames [first, last) of the batch; `out` is already sized for the whole batch.
}

namespace {
void extract_range(const uint8_t* frames, int first, int last, int width, int height,
                   const int* slot, const StripeSlot* slots, StripeOutput& out,
                   [[maybe_unused]] bool vector_blocks) {
  constexpr int kGroup = 16;
  std::vector<uint8_t> mx(width, 0), arg8(width, 0);
  std::vector<uint16_t> arg16(width, 0);
  std::vector<int> p(width, 0);
  const size_t frame = size_t(width) * height;
  // Both serve only the AVX-512 blocks (the portable path, measured, gains nothing from
  // prefetching). Results larger than the cache are streamed to memory (they would be
  // evicted before they are read); smaller ones stay in the cache for the next stage.
  [[maybe_unused]] stripe::Prefetch pf{frames + frame * first, frames + frame * last};
  [[maybe_unused]] const bool stream =
      size_t(last - first) * width * kOutputBytesPerColumn > kStreamOutputBytes;
  for (int i = first; i < last; ++i) {
    const uint8_t* f = frames + frame * i;
    const StripeSlot& sl = slots[slot[i]];
    // Rows fit a byte for the usual sensor heights, which keeps the scan in 8-bit lanes.
    int c0 = 0;
    if (height <= 256) {
      column_max8(f, width, height, mx.data(), arg8.data());
#if defined(RANGEX_STRIPE_BLOCK64)
      if (vector_blocks) {
        pf.skip_to(f + frame);  // the scan above has read this frame
        for (; c0 + 64 <= width; c0 += 64)
          stripe::column_block64(f, width, height, c0, mx.data(), arg8.data(), sl, out,
                                 size_t(i) * width, pf, stream);
      }
#endif
      for (int c = c0; c < width; ++c) p[c] = arg8[c];
    } else {
      column_max(f, width, width, height, mx.data(), arg16.data());
      for (int c = 0; c < width; ++c) p[c] = arg16[c];
    }
    // The columns left (all of them without AVX-512) in groups of 16, then one by one.
    for (; c0 + kGroup <= width; c0 += kGroup)
      column_group<kGroup>(f, width, height, c0, mx.data(), p.data(), sl, out, size_t(i) * width);
    for (; c0 < width; ++c0)
      column_group<1>(f, width, height, c0, mx.data(), p.data(), sl, out, size_t(i) * width);
  }
#if defined(RANGEX_STRIPE_BLOCK64)
  if (stream) _mm_sfence();  // streamed results are visible before the caller reads them
#endif
}

}  // namespace

void extract_stripes(const uint8_t* frames, int count, int width, int height, const int* slot,
                     const StripeSlot* slots, StripeOutput& out, int threads, bool vector_blocks) {
  out.resize(size_t(count) * width);
  threads = std::max(1, std::min(threads, count));
  if (threads == 1)
    return extract_range(frames, 0, count, width, height, slot, slots, out, vector_blocks);
  // Frames are independent: each thread takes a contiguous share and writes its own columns.
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back(extract_range, frames, count * t / threads, count * (t + 1) / threads, width,
                      height, slot, slots, std::ref(out), vector_blocks);
  for (auto& th : pool) th.join();
}

const char* stripe_vector_path() {
#if defined(__AVX512BW__)
  return "AVX-512 blocks of 64 columns";
#elif defined(__AVX2__)
  return "AVX2 blocks of 64 columns";
#else
  return "portable groups of 16 columns";
#endif
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
      out.width[o] = out.asym[o] = out.centroid[o] = 0.f;
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
      out.row[o] =
          stripe::method_row(sl.params.method, sums, k, binary, sl.scatter, centroid, asym);
      out.centroid[o] = centroid;
      out.asym[o] = asym;
      out.valid[o] = 1;
    }
}

}  // namespace rangex
