// Stage 3b, fan-beam projection: one work-item per (line, detector pixel), the length of the
// pixel's ray from the source through the meat, ray_path_length (server/core/ray_path.cpp)
// followed cell by cell in double as the CPU reference does.

#define MIN_SEGMENT_MM 1e-6  // as ray_path.cpp

inline double positive_span(double a, double b, double fa, double fb) {
  if (fa <= 0 && fb <= 0) return 0;
  if (fa >= 0 && fb >= 0) return b - a;
  const double root = a + (b - a) * fa / (fa - fb);
  return fa > 0 ? root - a : b - root;
}

kernel void project(global const float* profile, global const int* profile_valid,
                    global const float* top, int lines, global const int* lane_slot,
                    global const struct LaneGeomK* geom, int grid_n, int pixels,
                    global float* thickness, global int* thickness_valid) {
  const size_t o = get_global_id(0);
  if (o >= (size_t)lines * pixels) return;
  const int l = (int)(o / pixels), i = (int)(o % pixels);
  const struct LaneGeomK gp = geom[lane_slot[l]];
  global const float* h = profile + (size_t)l * grid_n;
  global const int* hv = profile_valid + (size_t)l * grid_n;
  const double xd = gp.first_pixel_x_mm + gp.pitch_mm * i;
  const double zd = gp.detector_z_mm + gp.pitch_z_mm * i;
  const double xs = gp.source_x_mm, zs = gp.source_z_mm;
  const double slope = (xs - xd) / (zs - zd);  // dx/dz along the ray
  const double sec = sqrt(1 + slope * slope);
  const double ztop = max((double)top[l], 1e-6);
  bool ok = true;
  double z = 0, len = 0;
  for (int guard = 0; guard < grid_n + 4 && z < ztop; ++guard) {
    const double x = xd + slope * (z - zd);
    const double fc = (x - gp.grid_x0_mm) / gp.grid_pitch_mm;
    int cell = (int)floor(fc);
    if (slope < 0 && fc == floor(fc)) cell -= 1;  // on a boundary moving left
    double zexit = ztop;
    if (slope > 0) {
      const double xb = gp.grid_x0_mm + (cell + 1) * gp.grid_pitch_mm;
      zexit = min(ztop, zd + (xb - xd) / slope);
    } else if (slope < 0) {
      const double xb = gp.grid_x0_mm + cell * gp.grid_pitch_mm;
      zexit = min(ztop, zd + (xb - xd) / slope);
    }
    if (cell < -1 || cell >= grid_n)
      if ((cell < -1 && slope <= 0) || (cell >= grid_n && slope >= 0)) break;
    if (zexit - z > MIN_SEGMENT_MM) {  // a segment of no length has no meat to sample
      double h0 = 0, h1 = 0;
      if (cell >= 0 && cell < grid_n) {
        if (!hv[cell])
          ok = false;
        else
          h0 = h[cell];
      }
      if (cell + 1 >= 0 && cell + 1 < grid_n) {
        if (!hv[cell + 1])
          ok = false;
        else
          h1 = h[cell + 1];
      }
      const double xc = gp.grid_x0_mm + cell * gp.grid_pitch_mm;
      const double ta = (xd + slope * (z - zd) - xc) / gp.grid_pitch_mm;
      const double tb = (xd + slope * (zexit - zd) - xc) / gp.grid_pitch_mm;
      len += positive_span(z, zexit, h0 + (h1 - h0) * ta - z, h0 + (h1 - h0) * tb - zexit);
    }
    if (zexit <= z) zexit = z + 1e-9;  // numerical guard: always advance
    z = zexit;
  }
  thickness[o] = ok ? (float)(len * sec) : NAN;
  thickness_valid[o] = ok ? 1 : 0;
}
