#version 450
// The pseudo-X-ray map of a batch of fillets: kernels/pseudo_xray.cl for Vulkan. One
// work-group per fillet walks its pixels with a stride of 256. X-ray DN and use flags are
// read from 32-bit words (no 8- or 16-bit storage feature needed); ln I from the host's table.
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
layout(std430, binding = 6) writeonly buffer LnP { float ln_p[]; };
layout(std430, binding = 7) writeonly buffer P { float p[]; };
layout(std430, binding = 8) writeonly buffer Residual { float residual[]; };
layout(std430, binding = 9) writeonly buffer Z { float z[]; };
layout(push_constant) uniform Push { FilletPush pc; };
// clang-format on

uint xray_at(int i) {
  return (xray_words[i >> 1] >> (16 * (i & 1))) & 0xffffu;
}
bool use_at(int i) {
  return ((use_words[i >> 2] >> (8 * (i & 3))) & 0xffu) != 0u;
}

void main() {
  const int f = int(gl_WorkGroupID.x);
  if (f >= pc.fillets) return;
  const FilletModelK m = models[f];
  const bool noise = m.noise_a > 0.0lf || m.noise_b > 0.0lf;
  for (int i = offsets[f] + int(gl_LocalInvocationID.x); i < offsets[f + 1]; i += 256) {
    if (!use_at(i)) {
      ln_p[i] = kNaN;
      p[i] = kNaN;
      residual[i] = kNaN;
      z[i] = kNaN;
      continue;
    }
    precise const double lpd = m.b0 + m.b1 * double(thickness[i]);
    const float lp = float(lpd);
    const float pp = exp(lp);
    precise const double rd = ln_table[xray_at(i)] - double(lp);
    const float r = float(rd);
    ln_p[i] = lp;
    p[i] = pp;
    residual[i] = r;
    if (noise) {
      const double I = double(pp);
      precise const double v = m.noise_a / I + m.noise_b / (I * I);
      z[i] = float(double(r) / sqrt(max(v, 1e-12lf)));
    } else {
      z[i] = kNaN;
    }
  }
}
