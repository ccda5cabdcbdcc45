// Stage 1 for CPU devices (PoCL): one work-item per 16 neighbouring columns of a frame, every
// step a uchar16 / float16 operation across them, as stripe_block64_avx2.cpp does it, so that
// a CPU runs the stages as vector instructions instead of one column at a time. The results
// are those of kernel `stripe`: rows outside a window add exact zeros to the sums. Used when
// the frame height fits a byte and the width is a multiple of 16.

inline int hmin16(uchar16 v) {
  const uchar8 a = min(v.lo, v.hi);
  const uchar4 b = min(a.lo, a.hi);
  const uchar2 c = min(b.lo, b.hi);
  return min(c.x, c.y);
}
inline int hmax16(uchar16 v) {
  const uchar8 a = max(v.lo, v.hi);
  const uchar4 b = max(a.lo, a.hi);
  const uchar2 c = max(b.lo, b.hi);
  return max(c.x, c.y);
}

// The half-maximum midpoint of column c (kernel stripe's binary method).
inline float half_max_column(global const uchar* f, int width, int height, int c, int m, int p) {
  const float th = 0.5f * (float)m;
  int l = p, h = p;
  while (l > 0 && (float)f[(size_t)(l - 1) * width + c] > th) --l;
  while (h < height - 1 && (float)f[(size_t)(h + 1) * width + c] > th) ++h;
  const float gl = f[(size_t)l * width + c], gh = f[(size_t)h * width + c];
  const float left = l > 0 ? (float)(l - 1) + (th - (float)f[(size_t)(l - 1) * width + c]) /
                                                  (gl - (float)f[(size_t)(l - 1) * width + c])
                           : (float)l - 0.5f;
  const float right = h < height - 1
                          ? (float)h + (gh - th) / (gh - (float)f[(size_t)(h + 1) * width + c])
                          : (float)h + 0.5f;
  return 0.5f * (left + right);
}

kernel void stripe16(global const uchar* frames, int count, int width, int height,
                     global const int* frame_slot, global const struct StripeSlotK* slots,
                     global const float* ln, global float* row, global float* peak,
                     global float* width_out, global float* asym_out, global float* centroid_out,
                     global int* valid) {
  const int groups = width / 16;
  const size_t gid = get_global_id(0);
  if (gid >= (size_t)count * groups) return;
  const int fi = (int)(gid / groups), c0 = (int)(gid % groups) * 16;
  global const uchar* frame = frames + (size_t)fi * width * height;
  global const uchar* f = frame + c0;
  const struct StripeSlotK sl = slots[frame_slot[fi]];

  // Column maxima and their first rows.
  uchar16 m = (uchar16)(0), p = (uchar16)(0);
  for (int r = 0; r < height; ++r) {
    const uchar16 v = vload16(0, f + (size_t)r * width);
    p = select(p, (uchar16)((uchar)r), v > m);
    m = max(m, v);
  }
  const char16 has_peak = sl.min_peak <= 0    ? (char16)(-1)
                          : sl.min_peak > 255 ? (char16)(0)
                                              : m >= (uchar16)((uchar)sl.min_peak);
  // Thresholds: g > T exactly when g > floor(T) for an integer g.
  const float16 T = sl.threshold_rel * convert_float16(m);
  const uchar16 Tb = convert_uchar16_sat(floor(T));

  // Window walks away from the peaks; the 3-point neighbours are picked up on the way.
  uchar16 lo = p, hi = p, a3 = m, c3 = m;
  if (any(has_peak)) {
    const int pmin = hmin16(select((uchar16)(255), p, has_peak));
    const int pmax = hmax16(select((uchar16)(0), p, has_peak));
    char16 live = has_peak;
    const uchar16 below = p + (uchar16)(1);
    for (int r = pmin + 1; r < height && any(live); ++r) {
      const uchar16 G = vload16(0, f + (size_t)r * width), R = (uchar16)((uchar)r);
      const char16 beyond = R > p, in = G > Tb;
      hi = select(hi, R, live & beyond & in);
      c3 = select(c3, G, R == below);
      live = live & (~beyond | in);
    }
    live = has_peak;
    const uchar16 above = p - (uchar16)(1);
    for (int r = pmax - 1; r >= 0 && any(live); --r) {
      const uchar16 G = vload16(0, f + (size_t)r * width), R = (uchar16)((uchar)r);
      const char16 beyond = R<p, in = G> Tb;
      lo = select(lo, R, live & beyond & in);
      a3 = select(a3, G, R == above);
      live = live & (~beyond | in);
    }
  }
  // Windows wider than max_width are glare.
  const int max_span = clamp(sl.max_width - 1, -1, 255);
  const char16 ok =
      max_span < 0 ? (char16)(0) : has_peak & ((uchar16)(hi - lo) <= (uchar16)((uchar)max_span));

  // 3-point peaks; a flat top peaks at the middle of its plateau.
  uchar a8[16], m8[16], c8[16], p8[16], lo8[16], hi8[16];
  char ok8[16], hp8[16];
  vstore16(a3, 0, a8);
  vstore16(m, 0, m8);
  vstore16(c3, 0, c8);
  vstore16(p, 0, p8);
  vstore16(lo, 0, lo8);
  vstore16(hi, 0, hi8);
  vstore16(ok, 0, ok8);
  vstore16(has_peak, 0, hp8);
  float la8[16], lb8[16], lc8[16];
  for (int k = 0; k < 16; ++k) {
    la8[k] = ln[a8[k]];
    lb8[k] = ln[m8[k]];
    lc8[k] = ln[c8[k]];
  }
  const float16 la = vload16(0, la8), lb = vload16(0, lb8), lc = vload16(0, lc8);
  const float16 pf = convert_float16(p), a = convert_float16(a3), b = convert_float16(m),
                c = convert_float16(c3);
  const float16 dg = la - 2 * lb + lc, dp = a - 2 * b + c;
  float16 gauss = select(pf, pf + 0.5f * (la - lc) / dg, dg < 0);
  float16 parab = select(pf, pf + 0.5f * (a - c) / dp, dp < 0);
  float g8[16], q8[16];
  vstore16(gauss, 0, g8);
  vstore16(parab, 0, q8);
  for (int k = 0; k < 16; ++k) {
    if (!ok8[k] || c8[k] != m8[k]) continue;
    int pe = p8[k];
    while (pe < hi8[k] && f[(size_t)(pe + 1) * width + k] == m8[k]) ++pe;
    if (pe != p8[k]) g8[k] = q8[k] = 0.5f * (float)(p8[k] + pe);
  }
  gauss = vload16(0, g8);

  // Window sums over the band of rows holding every valid window (w = g - T inside).
  float16 s0 = 0, s1 = 0, bl = 0, q0 = 0, q1 = 0;
  if (any(ok)) {
    const int r0 = hmin16(select((uchar16)(255), lo, ok));
    const int r1 = hmax16(select((uchar16)(0), hi, ok));
    for (int r = r0; r <= r1; ++r) {
      const uchar16 R = (uchar16)((uchar)r);
      const int16 in = convert_int16(ok & (R >= lo) & (R <= hi));
      const float16 g = convert_float16(vload16(0, f + (size_t)r * width));
      const float16 w = select((float16)(0.0f), g - T, in);
      const float yy = (float)r;
      const float16 frac = clamp(gauss - (yy - 0.5f), 0.0f, 1.0f);
      s0 += w;
      s1 += w * yy;
      bl += w * frac;
      q0 += w * w;
      q1 += w * w * yy;
    }
  }
  float s08[16], s18[16], bl8[16], q08[16], q18[16];
  vstore16(s0, 0, s08);
  vstore16(s1, 0, s18);
  vstore16(bl, 0, bl8);
  vstore16(q0, 0, q08);
  vstore16(q1, 0, q18);
  for (int k = 0; k < 16; ++k) {
    const size_t o = (size_t)fi * width + c0 + k;
    peak[o] = (float)m8[k];
    row[o] = NAN;
    valid[o] = 0;
    width_out[o] = asym_out[o] = centroid_out[o] = 0.f;
    if (!hp8[k]) continue;
    width_out[o] = (float)(hi8[k] - lo8[k] + 1);
    if (!ok8[k]) continue;
    const float centroid = s18[k] / s08[k];
    const float asym = (2 * bl8[k] - s08[k]) / s08[k];
    float r;
    switch (sl.method) {
      case METHOD_CENTROID:
        r = centroid;
        break;
      case METHOD_SQUARED:
        r = q18[k] / q08[k];
        break;
      case METHOD_BINARY:
        r = half_max_column(frame, width, height, c0 + k, m8[k], p8[k]);
        break;
      case METHOD_GAUSSIAN3:
        r = g8[k];
        break;
      case METHOD_PARABOLA:
        r = q8[k];
        break;
      case METHOD_SHIFTED:
        r = centroid + sl.k1;
        break;
      default:
        r = centroid + sl.k2_offset + sl.k2 * asym;
        break;
    }
    row[o] = r;
    centroid_out[o] = centroid;
    asym_out[o] = asym;
    valid[o] = 1;
  }
}
