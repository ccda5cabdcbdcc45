#version 450
// Stage 2, rectification: kernels/rectify.cl for Vulkan. One invocation per (frame, column).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 64) in;
// Its buffer blocks one a line (clang-format takes them for classes).
// clang-format off
layout(std430, binding = 0) readonly buffer Row { float row[]; };
layout(std430, binding = 1) readonly buffer Valid { int valid[]; };
layout(std430, binding = 2) readonly buffer FrameSlot { int frame_slot[]; };
layout(std430, binding = 3) readonly buffer Tables { RectTableK tables[]; };
layout(std430, binding = 4) readonly buffer Nodes { float nodes[]; };
layout(std430, binding = 5) writeonly buffer X { float x[]; };
layout(std430, binding = 6) writeonly buffer Z { float z[]; };
layout(std430, binding = 7) writeonly buffer OutValid { int out_valid[]; };
layout(push_constant) uniform Push { RectifyPush pc; };
// clang-format on

void main() {
  const uint o = gl_GlobalInvocationID.x;
  if (o >= uint(pc.count) * uint(pc.width)) return;
  const int fi = int(o / uint(pc.width)), c = int(o % uint(pc.width));
  if (valid[o] == 0) {
    x[o] = kNaN;
    z[o] = kNaN;
    out_valid[o] = 0;
    return;
  }
  const RectTableK t = tables[frame_slot[fi]];
  precise const float inv = 1.0 / float(t.step);
  precise const float gu = float(c) * inv, gv = row[o] * inv;
  const int i = min(int(gu), t.nu - 2);
  const int j = clamp(int(floor(gv)), 0, t.nv - 2);
  precise const float fu = gu - float(i), fv = gv - float(j);
  const int tx = t.offset, tz = t.offset + t.nu * t.nv;
  const int n00 = j * t.nu + i, n10 = n00 + 1, n01 = n00 + t.nu, n11 = n01 + 1;
  precise const float w00 = (1.0 - fu) * (1.0 - fv), w10 = fu * (1.0 - fv), w01 = (1.0 - fu) * fv,
                      w11 = fu * fv;
  precise const float xv =
      w00 * nodes[tx + n00] + w10 * nodes[tx + n10] + w01 * nodes[tx + n01] + w11 * nodes[tx + n11];
  precise const float zv =
      w00 * nodes[tz + n00] + w10 * nodes[tz + n10] + w01 * nodes[tz + n01] + w11 * nodes[tz + n11];
  x[o] = xv;
  z[o] = zv;
  out_valid[o] = 1;
}
