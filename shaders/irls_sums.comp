#version 450
// One IRLS iteration's weighted sums for a batch of fillets: kernels/pseudo_xray.cl
// (irls_sums) for Vulkan. One work-group per fillet; its 256 partial sums are reduced as a
// tree in shared memory, in double.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 256) in;
// Its buffer blocks one a line (clang-format takes them for classes).
// clang-format off
layout(std430, binding = 0) readonly buffer Thickness { float thickness[]; };
layout(std430, binding = 1) readonly buffer Xray { uint xray_words[]; };
layout(std430, binding = 2) readonly buffer Use { uint use_words[]; };
layout(std430, binding = 3) readonly buffer Offsets { int offsets[]; };
layout(std430, binding = 4) readonly buffer Models { FilletModelK models[]; };
layout(std430, binding = 5) readonly buffer LnTable { double ln_table[]; };
layout(std430, binding = 6) writeonly buffer R { double r[]; };
layout(std430, binding = 7) writeonly buffer Sums { double sums[]; };
layout(push_constant) uniform Push { FilletPush pc; };
// clang-format on

shared double part[256 * IRLS_SUMS];

uint xray_at(int i) {
  return (xray_words[i >> 1] >> (16 * (i & 1))) & 0xffffu;
}
bool use_at(int i) {
  return ((use_words[i >> 2] >> (8 * (i & 3))) & 0xffu) != 0u;
}

void main() {
  const int f = int(gl_WorkGroupID.x), lid = int(gl_LocalInvocationID.x);
  double s[IRLS_SUMS] = double[IRLS_SUMS](0.0lf, 0.0lf, 0.0lf, 0.0lf, 0.0lf, 0.0lf);
  if (f < pc.fillets) {
    const FilletModelK m = models[f];
    for (int i = offsets[f] + lid; i < offsets[f + 1]; i += 256) {
      if (!use_at(i)) {
        r[i] = double(kNaN);
        continue;
      }
      const double x = double(thickness[i]), y = ln_table[xray_at(i)];
      precise const double ri = y - (m.b0 + m.b1 * x);
      precise double w = 1.0lf;
      if (m.scale > 0.0lf) {
        precise const double u = ri / m.scale / m.c;
        w = abs(u) <= 1.0lf ? (1.0lf - u * u) * (1.0lf - u * u) : 0.0lf;
      }
      r[i] = ri;
      s[0] += w;
      s[1] += w * x;
      s[2] += w * y;
      s[3] += w * x * x;
      s[4] += w * x * y;
      s[5] += w * ri * ri;
    }
  }
  for (int k = 0; k < IRLS_SUMS; ++k) part[lid * IRLS_SUMS + k] = s[k];
  barrier();
  for (int span = 128; span > 0; span /= 2) {
    if (lid < span)
      for (int k = 0; k < IRLS_SUMS; ++k)
        part[lid * IRLS_SUMS + k] += part[(lid + span) * IRLS_SUMS + k];
    barrier();
  }
  if (lid == 0 && f < pc.fillets)
    for (int k = 0; k < IRLS_SUMS; ++k) sums[f * IRLS_SUMS + k] = part[k];
}
