#version 450
// Bone given the fat share, per pixel: kernels/dual_energy.cl (dual_energy_bone) for Vulkan,
// in double.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "shared/dual_energy.h"

layout(local_size_x = 64) in;
// Its buffer blocks one a line (clang-format takes them for classes).
// clang-format off
layout(std430, binding = 0) readonly buffer Basis { float basis[]; };
layout(std430, binding = 1) readonly buffer Thickness { float thickness[]; };
layout(std430, binding = 2) readonly buffer Phi { float phi[]; };
layout(std430, binding = 3) readonly buffer PhiVar { float phi_var[]; };
layout(std430, binding = 4) readonly buffer Params { DualEnergyK k; };
layout(std430, binding = 5) writeonly buffer Bone { float bone[]; };
layout(std430, binding = 6) writeonly buffer BoneSigma { float bone_sigma[]; };
layout(push_constant) uniform Push { DualEnergyPush pc; };
// clang-format on

void main() {
  const int p = int(gl_GlobalInvocationID.x);
  if (p >= pc.pixels) return;
  // lean (a, b), fat (a, b), bone (a, b) per mm
  const double l0 = k.basis[0], l1 = k.basis[1], l2 = k.basis[2], l3 = k.basis[3];
  const double l4 = k.basis[4], l5 = k.basis[5];
  const double a = double(basis[5 * p]), b = double(basis[5 * p + 1]);
  const double c2 = double(basis[5 * p + 2]), c3 = double(basis[5 * p + 3]);
  const double c4 = double(basis[5 * p + 4]);
  const double f = double(phi[p]), T = double(thickness[p]);
  precise const double sa = (1.0lf - f) * l0 + f * l2, sb = (1.0lf - f) * l1 + f * l3;
  precise const double da = l4 - sa, db = l5 - sb;
  precise const double ra = a - sa * T, rb = b - sb * T;
  precise const double ea = (l2 - l0) * T, eb = (l3 - l1) * T;
  const double vp = double(phi_var[p]);
  precise const double vt = k.var_t + pc.density_var * T * T;
  precise const double caa = c2 + sa * sa * vt + ea * ea * vp;
  precise const double cab = c3 + sa * sb * vt + ea * eb * vp;
  precise const double cbb = c4 + sb * sb * vt + eb * eb * vp;
  precise const double det = caa * cbb - cab * cab;
  precise const double ia = (cbb * da - cab * db) / det, ib = (caa * db - cab * da) / det;
  precise const double info = da * ia + db * ib;
  bone[p] = float((ra * ia + rb * ib) / info);
  bone_sigma[p] = float(1.0lf / sqrt(info));
}
