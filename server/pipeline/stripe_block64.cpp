#include "pipeline/stripe_block64.h"

#if defined(__AVX512BW__)
// GCC 12's intrinsic headers start some results from _mm512_undefined_*(), which its own
// -Wuninitialized reports inside the header.
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>

#include <algorithm>
#include <limits>

#include "pipeline/stripe_column.h"

namespace rangex::stripe {

namespace {

inline __m512i bytes(int v) {
  return _mm512_set1_epi8(char(v));
}

// Smallest byte of x (the mask's unused lanes already hold 255).
inline int min_u8(__m512i x) {
  const __m256i y = _mm256_min_epu8(_mm512_castsi512_si256(x), _mm512_extracti64x4_epi64(x, 1));
  __m128i z = _mm_min_epu8(_mm256_castsi256_si128(y), _mm256_extracti128_si256(y, 1));
  z = _mm_min_epu8(z, _mm_srli_si128(z, 8));
  return _mm_cvtsi128_si32(_mm_minpos_epu16(_mm_cvtepu8_epi16(z))) & 0xFFFF;
}
inline int max_u8(__m512i x) {
  return 255 - min_u8(_mm512_sub_epi8(bytes(255), x));
}

// Lanes 16j .. 16j+15 of a byte vector, widened to floats.
inline __m512 quarter_ps(const uint8_t* v, int j) {
  return _mm512_cvtepi32_ps(_mm512_cvtepu8_epi32(_mm_loadu_si128((const __m128i*)(v + 16 * j))));
}
inline __m512i quarter_epi32(const uint8_t* v, int j) {
  return _mm512_cvtepu8_epi32(_mm_loadu_si128((const __m128i*)(v + 16 * j)));
}
// Streaming stores write whole lines without first reading them into the cache.
inline void put(float* p, __m512 v, bool stream) {
  if (stream)
    _mm512_stream_ps(p, v);
  else
    _mm512_storeu_ps(p, v);
}
inline __mmask16 quarter(__mmask64 m, int j) {
  return __mmask16(m >> (16 * j));
}

// One window walk for the 64 lanes, from row `start` away from the peaks P in direction
// Dir (+1 down, -1 up): `edge` becomes each window's last row on that side and `next` the
// pixel next to the peak on that side. A lane stays live while its pixels exceed its
// threshold Tb; the walk ends when no lane is live.
template <int Dir>
void walk(const uint8_t* f, int width, int height, int c0, int start, __m512i P, __m512i Tb,
          __mmask64 live, __m512i& edge, __m512i& next, Prefetch& pf) {
  const __m512i beside = _mm512_add_epi8(P, bytes(Dir));
  for (int r = start; r >= 0 && r < height && live; r += Dir) {
    pf.step();
    const __m512i G = _mm512_loadu_si512(f + size_t(r) * width + c0), R = bytes(r);
    const __mmask64 beyond = Dir > 0 ? _mm512_cmpgt_epu8_mask(R, P) : _mm512_cmplt_epu8_mask(R, P);
    const __mmask64 in = _mm512_cmpgt_epu8_mask(G, Tb);
    edge = _mm512_mask_mov_epi8(edge, live & beyond & in, R);
    next = _mm512_mask_mov_epi8(next, _mm512_cmpeq_epi8_mask(R, beside), G);
    live &= ~beyond | in;
  }
}

// Window sums over the band of rows r0..r1 for the 64 lanes: w = g - T inside a lane's
// window, zero outside (stripe::accumulate, across lanes). Squares only for kSquared.
template <bool Squares>
void window_sums(const uint8_t* f, int width, int c0, int r0, int r1, __m512i lo, __m512i hi,
                 __mmask64 valid, const __m512* T, const __m512* gauss, float (*sums)[64],
                 Prefetch& pf) {
  __m512 s0[4], s1[4], bl[4], q0[4], q1[4];
  for (int j = 0; j < 4; ++j) s0[j] = s1[j] = bl[j] = q0[j] = q1[j] = _mm512_setzero_ps();
  const __m512 zero = _mm512_setzero_ps(), one = _mm512_set1_ps(1.0f);
  for (int r = r0; r <= r1; ++r) {
    const uint8_t* row = f + size_t(r) * width + c0;
    const __m512i R = bytes(r);
    const __mmask64 in = valid & _mm512_cmpge_epu8_mask(R, lo) & _mm512_cmple_epu8_mask(R, hi);
    pf.step();
    const __m512 y = _mm512_set1_ps(float(r)), edge = _mm512_set1_ps(float(r) - 0.5f);
#pragma GCC unroll 4
    for (int j = 0; j < 4; ++j) {
      const __m512 w = _mm512_maskz_sub_ps(quarter(in, j), quarter_ps(row, j), T[j]);
      const __m512 frac = _mm512_min_ps(_mm512_max_ps(_mm512_sub_ps(gauss[j], edge), zero), one);
      s0[j] = _mm512_add_ps(s0[j], w);
      s1[j] = _mm512_fmadd_ps(w, y, s1[j]);
      bl[j] = _mm512_fmadd_ps(w, frac, bl[j]);
      if constexpr (Squares) {
        const __m512 ww = _mm512_mul_ps(w, w);
        q0[j] = _mm512_add_ps(q0[j], ww);
        q1[j] = _mm512_fmadd_ps(ww, y, q1[j]);
      }
    }
  }
  for (int j = 0; j < 4; ++j) {
    _mm512_storeu_ps(sums[0] + 16 * j, s0[j]);
    _mm512_storeu_ps(sums[1] + 16 * j, s1[j]);
    _mm512_storeu_ps(sums[2] + 16 * j, bl[j]);
    _mm512_storeu_ps(sums[3] + 16 * j, q0[j]);
    _mm512_storeu_ps(sums[4] + 16 * j, q1[j]);
  }
}

}  // namespace

void column_block64(const uint8_t* f, int width, int height, int c0, const uint8_t* mx,
                    const uint8_t* arg, const StripeSlot& sl, StripeOutput& out, size_t o0,
                    Prefetch& pf, bool stream) {
  const StripeParams& sp = sl.params;
  const __m512i M = _mm512_loadu_si512(mx + c0), P = _mm512_loadu_si512(arg + c0);
  // Columns with a stripe: peak >= min_peak (config keeps min_peak in 1..255).
  const __mmask64 has_peak = sp.min_peak <= 0    ? ~__mmask64(0)
                             : sp.min_peak > 255 ? __mmask64(0)
                                                 : _mm512_cmpge_epu8_mask(M, bytes(sp.min_peak));

  // Thresholds T = rel * m as floats (for the weights) and as bytes: for an integer g,
  // g > T exactly when g > floor(T), so the walks compare bytes.
  const float rel = float(sp.threshold_rel);
  alignas(64) uint8_t m8[64], a8[64], c8[64], lo8[64], hi8[64], tb8[64];
  _mm512_store_si512(m8, M);
  __m512 T[4];
  for (int j = 0; j < 4; ++j) {
    T[j] = _mm512_mul_ps(_mm512_set1_ps(rel), quarter_ps(m8, j));
    const __m512i t = _mm512_min_epi32(
        _mm512_max_epi32(_mm512_cvttps_epi32(_mm512_floor_ps(T[j])), _mm512_setzero_si512()),
        _mm512_set1_epi32(255));
    _mm_store_si128((__m128i*)(tb8 + 16 * j), _mm512_cvtepi32_epi8(t));
  }
  const __m512i Tb = _mm512_load_si512(tb8);

  // Window walks (stripe_extract.cpp's window()): away from the peaks, a lane stays in its
  // window while its pixels exceed its threshold; the walk ends when every lane has left.
  // The 3-point neighbours are picked up on the way (they stay m at the frame's edge).
  __m512i lo = P, hi = P, a3 = M, c3 = M;
  if (has_peak) {
    const int pmin = min_u8(_mm512_mask_mov_epi8(bytes(255), has_peak, P));
    const int pmax = max_u8(_mm512_maskz_mov_epi8(has_peak, P));
    walk<+1>(f, width, height, c0, pmin + 1, P, Tb, has_peak, hi, c3, pf);
    walk<-1>(f, width, height, c0, pmax - 1, P, Tb, has_peak, lo, a3, pf);
  }
  _mm512_store_si512(a8, a3);
  _mm512_store_si512(c8, c3);
  _mm512_store_si512(lo8, lo);
  _mm512_store_si512(hi8, hi);

  // Windows wider than max_width are glare, not a stripe.
  const int max_span = std::clamp(sp.max_width - 1, -1, 255);
  const __mmask64 valid =
      max_span < 0 ? __mmask64(0)
                   : has_peak & _mm512_cmple_epu8_mask(_mm512_sub_epi8(hi, lo), bytes(max_span));

  // 3-point peaks (stripe::three_point_peaks, across lanes).
  const float* ln = ln_table().v;
  alignas(64) float gauss[64], parab[64];
  for (int j = 0; j < 4; ++j) {
    const __m512 a = quarter_ps(a8, j), b = quarter_ps(m8, j), c = quarter_ps(c8, j);
    const __m512 p = quarter_ps(arg + c0, j), half = _mm512_set1_ps(0.5f);
    const __m512 la = _mm512_i32gather_ps(quarter_epi32(a8, j), ln, 4);
    const __m512 lb = _mm512_i32gather_ps(quarter_epi32(m8, j), ln, 4);
    const __m512 lc = _mm512_i32gather_ps(quarter_epi32(c8, j), ln, 4);
    const __m512 two = _mm512_set1_ps(2.0f);
    const __m512 dg = _mm512_add_ps(_mm512_sub_ps(la, _mm512_mul_ps(two, lb)), lc);
    const __m512 dp = _mm512_add_ps(_mm512_sub_ps(a, _mm512_mul_ps(two, b)), c);
    const __mmask16 g_ok = _mm512_cmplt_ps_mask(dg, _mm512_setzero_ps());
    const __mmask16 p_ok = _mm512_cmplt_ps_mask(dp, _mm512_setzero_ps());
    const __m512 g =
        _mm512_add_ps(p, _mm512_div_ps(_mm512_mul_ps(half, _mm512_sub_ps(la, lc)), dg));
    const __m512 q = _mm512_add_ps(p, _mm512_div_ps(_mm512_mul_ps(half, _mm512_sub_ps(a, c)), dp));
    _mm512_store_ps(gauss + 16 * j, _mm512_mask_mov_ps(p, g_ok, g));
    _mm512_store_ps(parab + 16 * j, _mm512_mask_mov_ps(p, p_ok, q));
  }
  // A flat top (the next row equals the maximum, e.g. saturation) peaks at the middle of
  // its plateau; rare, so found lane by lane.
  for (__mmask64 flat = valid & _mm512_cmpeq_epi8_mask(c3, M); flat; flat &= flat - 1) {
    const int k = __builtin_ctzll(flat), c = c0 + k, p = arg[c];
    const int pe = plateau_end(f, width, c, p, hi8[k], m8[k]);
    if (pe != p) gauss[k] = parab[k] = 0.5f * float(p + pe);
  }

  // Window sums over the band of rows that holds every valid window of the block.
  alignas(64) float sums[5][64] = {};
  __m512 gv[4];
  for (int j = 0; j < 4; ++j) gv[j] = _mm512_load_ps(gauss + 16 * j);
  if (valid) {
    const int r0 = min_u8(_mm512_mask_mov_epi8(bytes(255), valid, lo));
    const int r1 = max_u8(_mm512_maskz_mov_epi8(valid, hi));
    if (sp.method == StripeMethod::kSquared)
      window_sums<true>(f, width, c0, r0, r1, lo, hi, valid, T, gv, sums, pf);
    else
      window_sums<false>(f, width, c0, r0, r1, lo, hi, valid, T, gv, sums, pf);
  }

  // The method's row (stripe::method_row, across lanes) and the outputs.
  const size_t o = o0 + c0;
  // The output arrays are 64-byte aligned, so a block starting at a multiple of 64
  // columns covers whole cache lines of each.
  stream = stream && o % 64 == 0;
  const ScatterConstants& sc = sl.scatter;
  const __m512 nan = _mm512_set1_ps(std::numeric_limits<float>::quiet_NaN());
  for (int j = 0; j < 4; ++j) {
    const __mmask16 v = quarter(valid, j);
    const __m512 s0 = _mm512_load_ps(sums[0] + 16 * j), s1 = _mm512_load_ps(sums[1] + 16 * j);
    const __m512 bl = _mm512_load_ps(sums[2] + 16 * j);
    const __m512 C = _mm512_maskz_div_ps(v, s1, s0);
    const __m512 A =
        _mm512_maskz_div_ps(v, _mm512_sub_ps(_mm512_add_ps(bl, bl), s0), s0);  // (L - U) / (L + U)
    __m512 row;
    switch (sp.method) {
      case StripeMethod::kCentroid:
        row = C;
        break;
      case StripeMethod::kSquared:
        row = _mm512_maskz_div_ps(v, _mm512_load_ps(sums[4] + 16 * j),
                                  _mm512_load_ps(sums[3] + 16 * j));
        break;
      case StripeMethod::kBinary: {
        alignas(64) float b[16] = {};
        for (__mmask16 m = v; m; m &= m - 1) {
          const int k = 16 * j + __builtin_ctz(m);
          b[k - 16 * j] = half_max_midpoint(f, width, height, c0 + k, m8[k], arg[c0 + k]);
        }
        row = _mm512_load_ps(b);
        break;
      }
      case StripeMethod::kGaussian3:
        row = _mm512_load_ps(gauss + 16 * j);
        break;
      case StripeMethod::kParabola:
        row = _mm512_load_ps(parab + 16 * j);
        break;
      case StripeMethod::kShifted:
        row = _mm512_add_ps(C, _mm512_set1_ps(float(sc.k1)));
        break;
      case StripeMethod::kModified:
      default:
        row = _mm512_fmadd_ps(_mm512_set1_ps(float(sc.k2)), A,
                              _mm512_add_ps(C, _mm512_set1_ps(float(sc.k2_offset))));
        break;
    }
    put(&out.row[o + 16 * j], _mm512_mask_mov_ps(nan, v, row), stream);
    put(&out.peak[o + 16 * j], quarter_ps(m8, j), stream);
    const __m512 span = _mm512_sub_ps(quarter_ps(hi8, j), quarter_ps(lo8, j));
    put(&out.width[o + 16 * j],
        _mm512_maskz_add_ps(quarter(has_peak, j), span, _mm512_set1_ps(1.0f)), stream);
    put(&out.centroid[o + 16 * j], C, stream);
    put(&out.asym[o + 16 * j], A, stream);
  }
  const __m512i valid8 = _mm512_maskz_mov_epi8(valid, bytes(1));
  if (stream)
    _mm512_stream_si512(reinterpret_cast<__m512i*>(&out.valid[o]), valid8);
  else
    _mm512_storeu_si512(&out.valid[o], valid8);
}

}  // namespace rangex::stripe

#endif
