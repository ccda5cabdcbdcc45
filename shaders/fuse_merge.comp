#version 450
// Stage 3a, fusion part 2: kernels/fusion.cl fuse_merge for Vulkan. One invocation per line
// merges the two cameras' grids, fills short gaps, counts, and keeps the highest sample.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 64) in;
// Its buffer blocks one a line (clang-format takes them for classes).
// clang-format off
layout(std430, binding = 0) readonly buffer Cam { float cam[]; };
layout(std430, binding = 1) readonly buffer LaneSlot { int lane_slot[]; };
layout(std430, binding = 2) readonly buffer Geom { LaneGeomK geom[]; };
layout(std430, binding = 3) buffer Profile { float profile[]; };
layout(std430, binding = 4) buffer ProfileValid { int profile_valid[]; };
layout(std430, binding = 5) writeonly buffer Counts { FusionCountK counts[]; };
layout(std430, binding = 6) writeonly buffer Top { float top[]; };
layout(push_constant) uniform Push { FusePush pc; };
// clang-format on

void main() {
  const int l = int(gl_GlobalInvocationID.x);
  if (l >= pc.lines) return;
  const int grid_n = pc.grid_n;
  const LaneGeomK p = geom[lane_slot[l]];
  const int a = l * 2 * grid_n, b = a + grid_n, o = l * grid_n;
  int both = 0, single_cam = 0, conflict = 0, filled = 0, missing = 0;
  for (int g = 0; g < grid_n; ++g) {
    const float av = cam[a + g], bv = cam[b + g];
    const bool va = !isnan(av), vb = !isnan(bv);
    if (va && vb) {
      if (double(abs(av - bv)) <= p.agree_tol_mm) {
        precise const float mean = 0.5 * (av + bv);
        profile[o + g] = mean;
        profile_valid[o + g] = 1;
        ++both;
      } else {
        profile[o + g] = kNaN;
        profile_valid[o + g] = 0;
        ++conflict;
      }
    } else if (va || vb) {
      profile[o + g] = va ? av : bv;
      profile_valid[o + g] = 1;
      ++single_cam;
    } else {
      profile[o + g] = kNaN;
      profile_valid[o + g] = 0;
    }
  }
  // Short gaps between valid samples are interpolated; longer ones stay invalid.
  int last = -1;
  for (int g = 0; g < grid_n; ++g) {
    if (profile_valid[o + g] == 0) continue;
    const int gap = g - last - 1;
    if (last >= 0 && gap > 0 && gap <= p.max_gap) {
      for (int k = last + 1; k < g; ++k) {
        precise const float t = float(k - last) / float(g - last);
        precise const float v = profile[o + last] + t * (profile[o + g] - profile[o + last]);
        profile[o + k] = v;
        profile_valid[o + k] = 1;
        ++filled;
      }
    }
    last = g;
  }
  float hmax = 0.0;
  for (int g = 0; g < grid_n; ++g) {
    if (profile_valid[o + g] == 0)
      ++missing;
    else
      hmax = max(hmax, profile[o + g]);
  }
  counts[l] = FusionCountK(both, single_cam, conflict, filled, missing, 0);
  top[l] = hmax;
}
