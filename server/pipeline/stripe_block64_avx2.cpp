// The 64-column block of stripe_block64.cpp for CPUs with AVX2 but not AVX-512: the same
// stages, the 64 byte lanes held as two 32-byte halves, masks as byte vectors (0 or 0xFF)
// instead of mask registers, and the floats in eight groups of eight. The window sums run
// over each half of the block in turn, so that their accumulators fit AVX2's 16 registers.
#include "pipeline/stripe_block64.h"

#if defined(__AVX2__) && !defined(__AVX512BW__)
#include <immintrin.h>

#include <algorithm>
#include <limits>

#include "pipeline/stripe_column.h"

namespace rangex::stripe {

namespace {

// 64 byte lanes, one per column.
struct V {
  __m256i a, b;
};
inline V bytes(int v) {
  const __m256i x = _mm256_set1_epi8(char(v));
  return {x, x};
}
inline V load(const uint8_t* p) {
  return {_mm256_loadu_si256(reinterpret_cast<const __m256i*>(p)),
          _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p + 32))};
}
inline void store(uint8_t* p, V v) {
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), v.a);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(p + 32), v.b);
}
inline V operator&(V x, V y) {
  return {_mm256_and_si256(x.a, y.a), _mm256_and_si256(x.b, y.b)};
}
// ~x & y
inline V andnot(V x, V y) {
  return {_mm256_andnot_si256(x.a, y.a), _mm256_andnot_si256(x.b, y.b)};
}
inline V eq(V x, V y) {
  return {_mm256_cmpeq_epi8(x.a, y.a), _mm256_cmpeq_epi8(x.b, y.b)};
}
inline __m256i gtu(__m256i x, __m256i y) {  // unsigned x > y
  const __m256i s = _mm256_set1_epi8(char(0x80));
  return _mm256_cmpgt_epi8(_mm256_xor_si256(x, s), _mm256_xor_si256(y, s));
}
inline V gt(V x, V y) {
  return {gtu(x.a, y.a), gtu(x.b, y.b)};
}
inline V lt(V x, V y) {
  return gt(y, x);
}
inline V ge(V x, V y) {
  return eq({_mm256_max_epu8(x.a, y.a), _mm256_max_epu8(x.b, y.b)}, x);
}
inline V le(V x, V y) {
  return eq({_mm256_min_epu8(x.a, y.a), _mm256_min_epu8(x.b, y.b)}, x);
}
inline V add8(V x, V y) {
  return {_mm256_add_epi8(x.a, y.a), _mm256_add_epi8(x.b, y.b)};
}
inline V sub8(V x, V y) {
  return {_mm256_sub_epi8(x.a, y.a), _mm256_sub_epi8(x.b, y.b)};
}
// y where m, else x
inline V blend(V x, V y, V m) {
  return {_mm256_blendv_epi8(x.a, y.a, m.a), _mm256_blendv_epi8(x.b, y.b, m.b)};
}
inline uint64_t bits(V m) {
  return uint64_t(uint32_t(_mm256_movemask_epi8(m.a))) |
         uint64_t(uint32_t(_mm256_movemask_epi8(m.b))) << 32;
}

inline int min_u8(V x) {
  const __m256i y = _mm256_min_epu8(x.a, x.b);
  __m128i z = _mm_min_epu8(_mm256_castsi256_si128(y), _mm256_extracti128_si256(y, 1));
  z = _mm_min_epu8(z, _mm_srli_si128(z, 8));
  return _mm_cvtsi128_si32(_mm_minpos_epu16(_mm_cvtepu8_epi16(z))) & 0xFFFF;
}
inline int max_u8(V x) {
  return 255 - min_u8(sub8(bytes(255), x));
}

// Lanes 8j .. 8j+7 of a byte array, widened to floats; of a byte mask, to a float mask.
inline __m256i eighth_epi32(const uint8_t* v, int j) {
  return _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(v + 8 * j)));
}
inline __m256 eighth_ps(const uint8_t* v, int j) {
  return _mm256_cvtepi32_ps(eighth_epi32(v, j));
}
inline __m256 eighth_mask(const uint8_t* m, int j) {
  return _mm256_castsi256_ps(
      _mm256_cvtepi8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(m + 8 * j))));
}
inline __m256 fmadd(__m256 a, __m256 b, __m256 c) {
#if defined(__FMA__)
  return _mm256_fmadd_ps(a, b, c);
#else
  return _mm256_add_ps(_mm256_mul_ps(a, b), c);
#endif
}
inline void put(float* p, __m256 v, bool stream) {
  if (stream)
    _mm256_stream_ps(p, v);
  else
    _mm256_storeu_ps(p, v);
}

// One window walk for the 64 lanes (stripe_block64.cpp's walk).
template <int Dir>
void walk(const uint8_t* f, int width, int height, int c0, int start, V P, V Tb, V live, V& edge,
          V& next, Prefetch& pf) {
  const V beside = add8(P, bytes(Dir));
  for (int r = start; r >= 0 && r < height && bits(live); r += Dir) {
    pf.step();
    const V G = load(f + size_t(r) * width + c0), R = bytes(r);
    const V beyond = Dir > 0 ? gt(R, P) : lt(R, P);
    const V in = gt(G, Tb);
    edge = blend(edge, R, live & beyond & in);
    next = blend(next, G, eq(R, beside));
    live = andnot(andnot(in, beyond), live);  // live & (~beyond | in)
  }
}

// Window sums over the band of rows r0..r1 (stripe_block64.cpp's window_sums), 32 lanes at
// a time.
template <bool Squares>
void window_sums(const uint8_t* f, int width, int c0, int r0, int r1, V lo, V hi, V valid,
                 const __m256* T, const __m256* gauss, float (*sums)[64], Prefetch& pf) {
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  for (int h = 0; h < 2; ++h) {
    const __m256i lo_h = h ? lo.b : lo.a, hi_h = h ? hi.b : hi.a, valid_h = h ? valid.b : valid.a;
    __m256 s0[4], s1[4], bl[4], q0[4], q1[4];
    for (int j = 0; j < 4; ++j) s0[j] = s1[j] = bl[j] = q0[j] = q1[j] = zero;
    for (int r = r0; r <= r1; ++r) {
      const uint8_t* row = f + size_t(r) * width + c0 + 32 * h;
      const __m256i R = _mm256_set1_epi8(char(r));
      const __m256i in = _mm256_and_si256(
          valid_h, _mm256_and_si256(_mm256_cmpeq_epi8(_mm256_max_epu8(R, lo_h), R),
                                    _mm256_cmpeq_epi8(_mm256_min_epu8(R, hi_h), R)));
      alignas(32) uint8_t in8[32];
      _mm256_store_si256(reinterpret_cast<__m256i*>(in8), in);
      if (h == 0) pf.step();
      const __m256 y = _mm256_set1_ps(float(r)), edge = _mm256_set1_ps(float(r) - 0.5f);
#pragma GCC unroll 4
      for (int j = 0; j < 4; ++j) {
        const __m256 w =
            _mm256_and_ps(_mm256_sub_ps(eighth_ps(row, j), T[4 * h + j]), eighth_mask(in8, j));
        const __m256 frac =
            _mm256_min_ps(_mm256_max_ps(_mm256_sub_ps(gauss[4 * h + j], edge), zero), one);
        s0[j] = _mm256_add_ps(s0[j], w);
        s1[j] = fmadd(w, y, s1[j]);
        bl[j] = fmadd(w, frac, bl[j]);
        if constexpr (Squares) {
          const __m256 ww = _mm256_mul_ps(w, w);
          q0[j] = _mm256_add_ps(q0[j], ww);
          q1[j] = fmadd(ww, y, q1[j]);
        }
      }
    }
    for (int j = 0; j < 4; ++j) {
      const int o = 32 * h + 8 * j;
      _mm256_storeu_ps(sums[0] + o, s0[j]);
      _mm256_storeu_ps(sums[1] + o, s1[j]);
      _mm256_storeu_ps(sums[2] + o, bl[j]);
      _mm256_storeu_ps(sums[3] + o, q0[j]);
      _mm256_storeu_ps(sums[4] + o, q1[j]);
    }
  }
}

}  // namespace

void column_block64(const uint8_t* f, int width, int height, int c0, const uint8_t* mx,
                    const uint8_t* arg, const StripeSlot& sl, StripeOutput& out, size_t o0,
                    Prefetch& pf, bool stream) {
  const StripeParams& sp = sl.params;
  const V M = load(mx + c0), P = load(arg + c0);
  const V has_peak = sp.min_peak <= 0    ? bytes(0xFF)
                     : sp.min_peak > 255 ? bytes(0)
                                         : ge(M, bytes(sp.min_peak));

  // Thresholds as floats and as bytes (g > T exactly when g > floor(T) for an integer g).
  const float rel = float(sp.threshold_rel);
  alignas(32) uint8_t m8[64], a8[64], c8[64], lo8[64], hi8[64], tb8[64], valid8[64], peak8[64];
  store(m8, M);
  store(peak8, has_peak);
  __m256 T[8];
  for (int j = 0; j < 8; ++j) {
    T[j] = _mm256_mul_ps(_mm256_set1_ps(rel), eighth_ps(m8, j));
    alignas(32) int32_t t[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(t),
                       _mm256_min_epi32(_mm256_max_epi32(_mm256_cvttps_epi32(_mm256_floor_ps(T[j])),
                                                         _mm256_setzero_si256()),
                                        _mm256_set1_epi32(255)));
    for (int k = 0; k < 8; ++k) tb8[8 * j + k] = uint8_t(t[k]);
  }
  const V Tb = load(tb8);

  // Window walks, picking up the 3-point neighbours on the way.
  V lo = P, hi = P, a3 = M, c3 = M;
  if (bits(has_peak)) {
    const int pmin = min_u8(blend(bytes(255), P, has_peak));
    const int pmax = max_u8(has_peak & P);
    walk<+1>(f, width, height, c0, pmin + 1, P, Tb, has_peak, hi, c3, pf);
    walk<-1>(f, width, height, c0, pmax - 1, P, Tb, has_peak, lo, a3, pf);
  }
  store(a8, a3);
  store(c8, c3);
  store(lo8, lo);
  store(hi8, hi);

  // Windows wider than max_width are glare, not a stripe.
  const int max_span = std::clamp(sp.max_width - 1, -1, 255);
  const V valid = max_span < 0 ? bytes(0) : has_peak & le(sub8(hi, lo), bytes(max_span));
  store(valid8, valid);

  // 3-point peaks.
  const float* ln = ln_table().v;
  alignas(32) float gauss[64], parab[64];
  const __m256 zero = _mm256_setzero_ps(), half = _mm256_set1_ps(0.5f), two = _mm256_set1_ps(2.0f);
  for (int j = 0; j < 8; ++j) {
    const __m256 a = eighth_ps(a8, j), b = eighth_ps(m8, j), c = eighth_ps(c8, j);
    const __m256 p = eighth_ps(arg + c0, j);
    const __m256 la = _mm256_i32gather_ps(ln, eighth_epi32(a8, j), 4);
    const __m256 lb = _mm256_i32gather_ps(ln, eighth_epi32(m8, j), 4);
    const __m256 lc = _mm256_i32gather_ps(ln, eighth_epi32(c8, j), 4);
    const __m256 dg = _mm256_add_ps(_mm256_sub_ps(la, _mm256_mul_ps(two, lb)), lc);
    const __m256 dp = _mm256_add_ps(_mm256_sub_ps(a, _mm256_mul_ps(two, b)), c);
    const __m256 g =
        _mm256_add_ps(p, _mm256_div_ps(_mm256_mul_ps(half, _mm256_sub_ps(la, lc)), dg));
    const __m256 q = _mm256_add_ps(p, _mm256_div_ps(_mm256_mul_ps(half, _mm256_sub_ps(a, c)), dp));
    _mm256_store_ps(gauss + 8 * j, _mm256_blendv_ps(p, g, _mm256_cmp_ps(dg, zero, _CMP_LT_OQ)));
    _mm256_store_ps(parab + 8 * j, _mm256_blendv_ps(p, q, _mm256_cmp_ps(dp, zero, _CMP_LT_OQ)));
  }
  // Flat tops peak at the middle of their plateau; rare, so found lane by lane.
  for (uint64_t flat = bits(valid & eq(c3, M)); flat; flat &= flat - 1) {
    const int k = __builtin_ctzll(flat), c = c0 + k, p = arg[c];
    const int pe = plateau_end(f, width, c, p, hi8[k], m8[k]);
    if (pe != p) gauss[k] = parab[k] = 0.5f * float(p + pe);
  }

  // Window sums over the band of rows that holds every valid window of the block.
  alignas(32) float sums[5][64] = {};
  __m256 gv[8];
  for (int j = 0; j < 8; ++j) gv[j] = _mm256_load_ps(gauss + 8 * j);
  if (bits(valid)) {
    const int r0 = min_u8(blend(bytes(255), lo, valid));
    const int r1 = max_u8(valid & hi);
    if (sp.method == StripeMethod::kSquared)
      window_sums<true>(f, width, c0, r0, r1, lo, hi, valid, T, gv, sums, pf);
    else
      window_sums<false>(f, width, c0, r0, r1, lo, hi, valid, T, gv, sums, pf);
  }

  // The method's row and the outputs.
  const size_t o = o0 + c0;
  stream = stream && o % 64 == 0;
  const ScatterConstants& sc = sl.scatter;
  const __m256 nan = _mm256_set1_ps(std::numeric_limits<float>::quiet_NaN());
  const __m256 one = _mm256_set1_ps(1.0f);
  for (int j = 0; j < 8; ++j) {
    const __m256 v = eighth_mask(valid8, j);
    const __m256 s0 = _mm256_load_ps(sums[0] + 8 * j), s1 = _mm256_load_ps(sums[1] + 8 * j);
    const __m256 bl = _mm256_load_ps(sums[2] + 8 * j);
    const __m256 C = _mm256_and_ps(_mm256_div_ps(s1, s0), v);
    const __m256 A = _mm256_and_ps(_mm256_div_ps(_mm256_sub_ps(_mm256_add_ps(bl, bl), s0), s0), v);
    __m256 row;
    switch (sp.method) {
      case StripeMethod::kCentroid:
        row = C;
        break;
      case StripeMethod::kSquared:
        row = _mm256_div_ps(_mm256_load_ps(sums[4] + 8 * j), _mm256_load_ps(sums[3] + 8 * j));
        break;
      case StripeMethod::kBinary: {
        alignas(32) float b[8] = {};
        for (int k = 0; k < 8; ++k)
          if (valid8[8 * j + k])
            b[k] = half_max_midpoint(f, width, height, c0 + 8 * j + k, m8[8 * j + k],
                                     arg[c0 + 8 * j + k]);
        row = _mm256_load_ps(b);
        break;
      }
      case StripeMethod::kGaussian3:
        row = _mm256_load_ps(gauss + 8 * j);
        break;
      case StripeMethod::kParabola:
        row = _mm256_load_ps(parab + 8 * j);
        break;
      case StripeMethod::kShifted:
        row = _mm256_add_ps(C, _mm256_set1_ps(float(sc.k1)));
        break;
      case StripeMethod::kModified:
      default:
        row = fmadd(_mm256_set1_ps(float(sc.k2)), A,
                    _mm256_add_ps(C, _mm256_set1_ps(float(sc.k2_offset))));
        break;
    }
    put(&out.row[o + 8 * j], _mm256_blendv_ps(nan, row, v), stream);
    put(&out.peak[o + 8 * j], eighth_ps(m8, j), stream);
    const __m256 span = _mm256_sub_ps(eighth_ps(hi8, j), eighth_ps(lo8, j));
    put(&out.width[o + 8 * j], _mm256_and_ps(_mm256_add_ps(span, one), eighth_mask(peak8, j)),
        stream);
    put(&out.centroid[o + 8 * j], C, stream);
    put(&out.asym[o + 8 * j], A, stream);
  }
  const V one8 = valid & bytes(1);
  if (stream) {
    _mm256_stream_si256(reinterpret_cast<__m256i*>(&out.valid[o]), one8.a);
    _mm256_stream_si256(reinterpret_cast<__m256i*>(&out.valid[o + 32]), one8.b);
  } else {
    store(&out.valid[o], one8);
  }
}

}  // namespace rangex::stripe

#endif
