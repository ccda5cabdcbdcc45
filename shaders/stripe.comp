#version 450
// Stage 1, stripe extraction: kernels/stripe.cl (and the CPU reference it follows) for
// Vulkan. One invocation per (frame, column).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 64) in;
// Its buffer blocks one a line (clang-format takes them for classes).
// clang-format off
layout(std430, binding = 0) readonly buffer Frames { uint frames[]; };
layout(std430, binding = 1) readonly buffer FrameSlot { int frame_slot[]; };
layout(std430, binding = 2) readonly buffer Slots { StripeSlotK slots[]; };
layout(std430, binding = 3) readonly buffer Ln { float ln_table[]; };
layout(std430, binding = 4) writeonly buffer Row { float row[]; };
layout(std430, binding = 5) writeonly buffer Peak { float peak[]; };
layout(std430, binding = 6) writeonly buffer Width { float width_out[]; };
layout(std430, binding = 7) writeonly buffer Asym { float asym_out[]; };
layout(std430, binding = 8) writeonly buffer Centroid { float centroid_out[]; };
layout(std430, binding = 9) writeonly buffer Valid { int valid[]; };
layout(push_constant) uniform Push { StripePush pc; };
// clang-format on

uint frame_base;  // byte offset of this invocation's frame

int pxi(int y, int c) {
  const uint i = frame_base + uint(y) * uint(pc.width) + uint(c);
  return int((frames[i >> 2] >> ((i & 3u) * 8u)) & 0xFFu);
}
float px(int y, int c) {
  return float(pxi(y, c));
}

void main() {
  const uint gid = gl_GlobalInvocationID.x;
  if (gid >= uint(pc.count) * uint(pc.width)) return;
  const int fi = int(gid / uint(pc.width)), c = int(gid % uint(pc.width));
  const int width = pc.width, height = pc.height;
  frame_base = uint(fi) * uint(width) * uint(height);
  const StripeSlotK sl = slots[frame_slot[fi]];
  // The peak: the first row of the column's maximum.
  int m = 0, p = 0;
  for (int r = 0; r < height; ++r) {
    const int v = pxi(r, c);
    if (v > m) {
      m = v;
      p = r;
    }
  }
  peak[gid] = float(m);
  row[gid] = kNaN;
  valid[gid] = 0;
  width_out[gid] = 0.0;
  asym_out[gid] = 0.0;
  centroid_out[gid] = 0.0;
  if (m < sl.min_peak) return;
  // The window: the connected run above T around the peak; the flat top at the peak.
  precise const float T = sl.threshold_rel * float(m);
  int lo = p, hi = p;
  while (lo > 0 && px(lo - 1, c) > T) --lo;
  while (hi < height - 1 && px(hi + 1, c) > T) ++hi;
  int pe = p;
  while (pe < hi && pxi(pe + 1, c) == m) ++pe;
  width_out[gid] = float(hi - lo + 1);
  if (hi - lo + 1 > sl.max_width) return;  // glare
  // 3-point peaks: a plateau's midpoint, else the log-parabola and parabola vertices.
  const int a = pxi(max(p - 1, 0), c), b = m, cc = pxi(min(p + 1, height - 1), c);
  precise float gauss = 0.5 * float(p + pe);
  precise float parab = gauss;
  if (pe == p) {
    const float la = ln_table[a], lb = ln_table[b], lc = ln_table[cc];
    precise const float dg = la - 2.0 * lb + lc;
    const float dp = float(a - 2 * b + cc);
    if (dg < 0.0) gauss = float(p) + 0.5 * (la - lc) / dg;
    if (dp < 0.0) parab = float(p) + 0.5 * float(a - cc) / dp;
  }
  // Window sums with weights w = g - T.
  precise float s0 = 0.0, s1 = 0.0, q0 = 0.0, q1 = 0.0, below = 0.0;
  for (int y = lo; y <= hi; ++y) {
    precise const float w = px(y, c) - T;
    const float yy = float(y);
    precise const float frac = clamp(gauss - (yy - 0.5), 0.0, 1.0);
    s0 += w;
    s1 += w * yy;
    q0 += w * w;
    q1 += w * w * yy;
    below += w * frac;
  }
  // The half-maximum midpoint, for the binary method only.
  precise float binary = 0.0;
  if (sl.method == METHOD_BINARY) {
    const float th = 0.5 * float(m);
    int l = p, h = p;
    while (l > 0 && px(l - 1, c) > th) --l;
    while (h < height - 1 && px(h + 1, c) > th) ++h;
    precise const float left =
        l > 0 ? float(l - 1) + (th - px(l - 1, c)) / (px(l, c) - px(l - 1, c)) : float(l) - 0.5;
    precise const float right =
        h < height - 1 ? float(h) + (px(h, c) - th) / (px(h, c) - px(h + 1, c)) : float(h) + 0.5;
    binary = 0.5 * (left + right);
  }
  // The method's row.
  precise const float cen = s1 / s0;  // the plain centroid ("centroid" is a GLSL keyword)
  precise const float asym = (2.0 * below - s0) / s0;
  precise float r;
  switch (sl.method) {
    case METHOD_CENTROID:
      r = cen;
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
      r = cen + sl.k1;
      break;
    default:
      r = cen + sl.k2_offset + sl.k2 * asym;
      break;
  }
  row[gid] = r;
  centroid_out[gid] = cen;
  asym_out[gid] = asym;
  valid[gid] = 1;
}
