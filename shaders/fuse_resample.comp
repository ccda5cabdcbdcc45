#version 450
// Stage 3a, fusion part 1: kernels/fusion.cl fuse_resample for Vulkan. One invocation per
// (line, camera) walks the columns and resamples the polyline onto the lane's grid.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 64) in;
// Its buffer blocks one a line (clang-format takes them for classes).
// clang-format off
layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) readonly buffer Z { float z[]; };
layout(std430, binding = 2) readonly buffer Valid { int valid[]; };
layout(std430, binding = 3) readonly buffer LaneSlot { int lane_slot[]; };
layout(std430, binding = 4) readonly buffer Geom { LaneGeomK geom[]; };
layout(std430, binding = 5) buffer Cam { float cam[]; };
layout(push_constant) uniform Push { FusePush pc; };
// clang-format on

void main() {
  const int id = int(gl_GlobalInvocationID.x);
  if (id >= pc.lines * 2) return;
  const int l = id / 2, width = pc.width, grid_n = pc.grid_n;
  const LaneGeomK p = geom[lane_slot[l]];
  const int f = id * width;  // [line][camera][column]
  const int base = id * grid_n;
  for (int g = 0; g < grid_n; ++g) cam[base + g] = kNaN;
  const double inv = 1.0lf / p.grid_pitch_mm;
  for (int c = 0; c + 1 < width; ++c) {
    if (valid[f + c] == 0 || valid[f + c + 1] == 0) continue;
    const double xa = double(x[f + c]), xb = double(x[f + c + 1]);
    if (abs(xb - xa) > p.max_column_step_mm || xa == xb) continue;
    const double lo = min(xa, xb), hi = max(xa, xb);
    const int g0 = max(0, int(ceil((lo - p.grid_x0_mm) * inv)));
    const int g1 = min(grid_n - 1, int(floor((hi - p.grid_x0_mm) * inv)));
    for (int g = g0; g <= g1; ++g) {
      precise const double xg = p.grid_x0_mm + double(g) * p.grid_pitch_mm;
      precise const double t = (xg - xa) / (xb - xa);
      precise const double zd = double(z[f + c]) + t * (double(z[f + c + 1]) - double(z[f + c]));
      const float zg = float(zd);
      const float cur = cam[base + g];
      cam[base + g] = isnan(cur) ? zg : max(cur, zg);
    }
  }
}
