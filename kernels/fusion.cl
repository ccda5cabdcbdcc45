// Stage 3a, two-camera fusion, fuse_profiles (server/pipeline/profile_fusion.cpp) in two
// kernels: each camera's column polyline resampled onto the lane's grid (one work-item per
// line and camera, walking the columns as the CPU does), then per line the two grids merged,
// short gaps filled, counts taken and the highest valid sample kept for the projection.

kernel void fuse_resample(global const float* x, global const float* z, global const int* valid,
                          int width, int lines, global const int* lane_slot,
                          global const struct LaneGeomK* geom, int grid_n, global float* cam) {
  const int id = (int)get_global_id(0);
  if (id >= lines * 2) return;
  const int l = id / 2;
  const struct LaneGeomK p = geom[lane_slot[l]];
  const size_t f = (size_t)id * width;  // [line][camera][column]
  global float* grid = cam + (size_t)id * grid_n;
  for (int g = 0; g < grid_n; ++g) grid[g] = NAN;
  const double inv = 1.0 / p.grid_pitch_mm;
  for (int c = 0; c + 1 < width; ++c) {
    if (!valid[f + c] || !valid[f + c + 1]) continue;
    const double xa = x[f + c], xb = x[f + c + 1];
    if (fabs(xb - xa) > p.max_column_step_mm || xa == xb) continue;
    const double lo = min(xa, xb), hi = max(xa, xb);
    const int g0 = max(0, (int)ceil((lo - p.grid_x0_mm) * inv));
    const int g1 = min(grid_n - 1, (int)floor((hi - p.grid_x0_mm) * inv));
    for (int g = g0; g <= g1; ++g) {
      const double xg = p.grid_x0_mm + g * p.grid_pitch_mm;
      const double t = (xg - xa) / (xb - xa);
      const float zg = (float)(z[f + c] + t * (z[f + c + 1] - z[f + c]));
      grid[g] = isnan(grid[g]) ? zg : fmax(grid[g], zg);
    }
  }
}

kernel void fuse_merge(global const float* cam, int lines, global const int* lane_slot,
                       global const struct LaneGeomK* geom, int grid_n, global float* profile,
                       global int* profile_valid, global struct FusionCountK* counts,
                       global float* top) {
  const int l = (int)get_global_id(0);
  if (l >= lines) return;
  const struct LaneGeomK p = geom[lane_slot[l]];
  global const float* a = cam + (size_t)l * 2 * grid_n;
  global const float* b = a + grid_n;
  global float* out = profile + (size_t)l * grid_n;
  global int* ov = profile_valid + (size_t)l * grid_n;
  struct FusionCountK n = {0, 0, 0, 0, 0, 0};
  for (int g = 0; g < grid_n; ++g) {
    const bool va = !isnan(a[g]), vb = !isnan(b[g]);
    if (va && vb) {
      if ((double)fabs(a[g] - b[g]) <= p.agree_tol_mm) {
        out[g] = 0.5f * (a[g] + b[g]);
        ov[g] = 1;
        ++n.both;
      } else {
        out[g] = NAN;
        ov[g] = 0;
        ++n.conflict;
      }
    } else if (va || vb) {
      out[g] = va ? a[g] : b[g];
      ov[g] = 1;
      ++n.single_cam;
    } else {
      out[g] = NAN;
      ov[g] = 0;
    }
  }
  // Short gaps between valid samples are interpolated; longer ones stay invalid.
  int last = -1;
  for (int g = 0; g < grid_n; ++g) {
    if (!ov[g]) continue;
    const int gap = g - last - 1;
    if (last >= 0 && gap > 0 && gap <= p.max_gap) {
      for (int k = last + 1; k < g; ++k) {
        const float t = (float)(k - last) / (float)(g - last);
        out[k] = out[last] + t * (out[g] - out[last]);
        ov[k] = 1;
        ++n.filled;
      }
    }
    last = g;
  }
  float hmax = 0;
  for (int g = 0; g < grid_n; ++g) {
    n.missing += ov[g] ? 0 : 1;
    if (ov[g]) hmax = fmax(hmax, out[g]);
  }
  counts[l] = n;
  top[l] = hmax;
}
