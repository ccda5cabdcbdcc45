#version 450
// Stage 3b, fan-beam projection: kernels/projection.cl for Vulkan. One invocation per
// (line, detector pixel) follows the ray cell by cell in double.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 64) in;
// Its buffer blocks one a line (clang-format takes them for classes).
// clang-format off
layout(std430, binding = 0) readonly buffer Profile { float profile[]; };
layout(std430, binding = 1) readonly buffer ProfileValid { int profile_valid[]; };
layout(std430, binding = 2) readonly buffer Top { float top[]; };
layout(std430, binding = 3) readonly buffer LaneSlot { int lane_slot[]; };
layout(std430, binding = 4) readonly buffer Geom { LaneGeomK geom[]; };
layout(std430, binding = 5) writeonly buffer Thickness { float thickness[]; };
layout(std430, binding = 6) writeonly buffer ThicknessValid { int thickness_valid[]; };
layout(push_constant) uniform Push { ProjectPush pc; };
// clang-format on

const double kMinSegmentMm = 1e-6lf;  // as ray_path.cpp

double positive_span(double a, double b, double fa, double fb) {
  if (fa <= 0.0lf && fb <= 0.0lf) return 0.0lf;
  if (fa >= 0.0lf && fb >= 0.0lf) return b - a;
  precise const double root = a + (b - a) * fa / (fa - fb);
  return fa > 0.0lf ? root - a : b - root;
}

void main() {
  const uint o = gl_GlobalInvocationID.x;
  if (o >= uint(pc.lines) * uint(pc.pixels)) return;
  const int l = int(o / uint(pc.pixels)), i = int(o % uint(pc.pixels));
  const int grid_n = pc.grid_n, h = l * grid_n;
  const LaneGeomK gp = geom[lane_slot[l]];
  precise const double xd = gp.first_pixel_x_mm + gp.pitch_mm * double(i);
  precise const double zd = gp.detector_z_mm + gp.pitch_z_mm * double(i);
  const double xs = gp.source_x_mm, zs = gp.source_z_mm;
  precise const double slope = (xs - xd) / (zs - zd);  // dx/dz along the ray
  precise const double sec = sqrt(1.0lf + slope * slope);
  const double ztop = max(double(top[l]), 1e-6lf);
  bool ok = true;
  precise double z = 0.0lf, len = 0.0lf;
  for (int guard = 0; guard < grid_n + 4 && z < ztop; ++guard) {
    precise const double x = xd + slope * (z - zd);
    precise const double fc = (x - gp.grid_x0_mm) / gp.grid_pitch_mm;
    int cell = int(floor(fc));
    if (slope < 0.0lf && fc == floor(fc)) cell -= 1;  // on a boundary moving left
    precise double zexit = ztop;
    if (slope > 0.0lf) {
      precise const double xb = gp.grid_x0_mm + double(cell + 1) * gp.grid_pitch_mm;
      zexit = min(ztop, zd + (xb - xd) / slope);
    } else if (slope < 0.0lf) {
      precise const double xb = gp.grid_x0_mm + double(cell) * gp.grid_pitch_mm;
      zexit = min(ztop, zd + (xb - xd) / slope);
    }
    if (cell < -1 || cell >= grid_n)
      if ((cell < -1 && slope <= 0.0lf) || (cell >= grid_n && slope >= 0.0lf)) break;
    if (zexit - z > kMinSegmentMm) {  // a segment of no length has no meat to sample
      double h0 = 0.0lf, h1 = 0.0lf;
      if (cell >= 0 && cell < grid_n) {
        if (profile_valid[h + cell] == 0)
          ok = false;
        else
          h0 = double(profile[h + cell]);
      }
      if (cell + 1 >= 0 && cell + 1 < grid_n) {
        if (profile_valid[h + cell + 1] == 0)
          ok = false;
        else
          h1 = double(profile[h + cell + 1]);
      }
      precise const double xc = gp.grid_x0_mm + double(cell) * gp.grid_pitch_mm;
      precise const double ta = (xd + slope * (z - zd) - xc) / gp.grid_pitch_mm;
      precise const double tb = (xd + slope * (zexit - zd) - xc) / gp.grid_pitch_mm;
      len += positive_span(z, zexit, h0 + (h1 - h0) * ta - z, h0 + (h1 - h0) * tb - zexit);
    }
    if (zexit <= z) zexit = z + 1e-9lf;  // numerical guard: always advance
    z = zexit;
  }
  thickness[o] = ok ? float(len * sec) : kNaN;
  thickness_valid[o] = ok ? 1 : 0;
}
