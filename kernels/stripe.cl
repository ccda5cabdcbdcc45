// Stage 1, stripe extraction: one work-item per (frame, column), the CPU reference
// extract_stripes_reference (server/pipeline/stripe_extract.cpp, stripe_column.h) line by
// line. Neighbouring work-items read neighbouring bytes of each row.
//   frames: count Mono8 frames, height x width; frame_slot[f] = lane * 2 + camera.
//   Outputs per column: row (NaN when invalid), peak, width, asym, centroid, valid (0/1).

inline float px(global const uchar* f, int width, int y, int c) {
  return (float)f[(size_t)y * width + c];
}

kernel void stripe(global const uchar* frames, int count, int width, int height,
                   global const int* frame_slot, global const struct StripeSlotK* slots,
                   global const float* ln, global float* row, global float* peak,
                   global float* width_out, global float* asym_out, global float* centroid_out,
                   global int* valid) {
  const size_t gid = get_global_id(0);
  if (gid >= (size_t)count * width) return;
  const int fi = (int)(gid / width), c = (int)(gid % width);
  global const uchar* f = frames + (size_t)fi * width * height;
  const struct StripeSlotK sl = slots[frame_slot[fi]];
  // The peak: the first row of the column's maximum.
  int m = 0, p = 0;
  for (int r = 0; r < height; ++r) {
    const int v = f[(size_t)r * width + c];
    if (v > m) {
      m = v;
      p = r;
    }
  }
  peak[gid] = (float)m;
  row[gid] = NAN;
  valid[gid] = 0;
  width_out[gid] = asym_out[gid] = centroid_out[gid] = 0.f;
  if (m < sl.min_peak) return;
  // The window: the connected run above T around the peak; the flat top at the peak.
  const float T = sl.threshold_rel * (float)m;
  int lo = p, hi = p;
  while (lo > 0 && px(f, width, lo - 1, c) > T) --lo;
  while (hi < height - 1 && px(f, width, hi + 1, c) > T) ++hi;
  int pe = p;
  while (pe < hi && f[(size_t)(pe + 1) * width + c] == m) ++pe;
  width_out[gid] = (float)(hi - lo + 1);
  if (hi - lo + 1 > sl.max_width) return;  // glare
  // 3-point peaks (three_point_peaks): a plateau's midpoint, else the log-parabola and
  // parabola vertices.
  const int a = f[(size_t)max(p - 1, 0) * width + c];
  const int b = m;
  const int cc = f[(size_t)min(p + 1, height - 1) * width + c];
  float gauss = 0.5f * (float)(p + pe), parab = gauss;
  if (pe == p) {
    const float la = ln[a], lb = ln[b], lc = ln[cc];
    const float dg = la - 2 * lb + lc, dp = (float)(a - 2 * b + cc);
    if (dg < 0) gauss = (float)p + 0.5f * (la - lc) / dg;
    if (dp < 0) parab = (float)p + 0.5f * (float)(a - cc) / dp;
  }
  // Window sums with weights w = g - T (accumulate).
  float s0 = 0, s1 = 0, q0 = 0, q1 = 0, below = 0;
  for (int y = lo; y <= hi; ++y) {
    const float w = px(f, width, y, c) - T, yy = (float)y;
    const float frac = clamp(gauss - (yy - 0.5f), 0.0f, 1.0f);
    s0 += w;
    s1 += w * yy;
    q0 += w * w;
    q1 += w * w * yy;
    below += w * frac;
  }
  // The half-maximum midpoint (half_max_midpoint), for the binary method only.
  float binary = 0.f;
  if (sl.method == METHOD_BINARY) {
    const float th = 0.5f * (float)m;
    int l = p, h = p;
    while (l > 0 && px(f, width, l - 1, c) > th) --l;
    while (h < height - 1 && px(f, width, h + 1, c) > th) ++h;
    const float left = l > 0 ? (float)(l - 1) + (th - px(f, width, l - 1, c)) /
                                                    (px(f, width, l, c) - px(f, width, l - 1, c))
                             : (float)l - 0.5f;
    const float right =
        h < height - 1
            ? (float)h + (px(f, width, h, c) - th) / (px(f, width, h, c) - px(f, width, h + 1, c))
            : (float)h + 0.5f;
    binary = 0.5f * (left + right);
  }
  // The method's row (method_row).
  const float centroid = s1 / s0;
  const float asym = (2 * below - s0) / s0;
  float r;
  switch (sl.method) {
    case METHOD_CENTROID:
      r = centroid;
      break;
    case METHOD_SQUARED:
      r = q1 / q0;
      break;
    case METHOD_BINARY:
      r = binary;
      break;
    case METHOD_GAUSSIAN3:
      r = gauss;
      break;
    case METHOD_PARABOLA:
      r = parab;
      break;
    case METHOD_SHIFTED:
      r = centroid + sl.k1;
      break;
    default:
      r = centroid + sl.k2_offset + sl.k2 * asym;
      break;
  }
  row[gid] = r;
  centroid_out[gid] = centroid;
  asym_out[gid] = asym;
  valid[gid] = 1;
}
