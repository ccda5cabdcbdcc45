#include "pipeline/ray_table.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/no_value.h"
#include "core/ray_path.h"

namespace rangex {

RayTable build_ray_table(const FanBeam& fb, const FusionParams& grid, double z_max_mm) {
  if (!(z_max_mm > 0)) fail("ray table: z_max must be > 0 (got ", z_max_mm, ")");
  if (!(grid.grid_pitch_mm > 0) || grid.grid_samples < 2)
    fail("ray table: the fusion grid needs a pitch > 0 and 2 samples or more");
  RayTable t;
  t.z_max_mm = z_max_mm;
  t.pixels = fb.pixels;
  t.grid_n = grid.grid_samples;
  t.x0_mm = grid.grid_x0_mm;
  t.pitch_mm = grid.grid_pitch_mm;
  t.beam = fb;
  const int n = t.grid_n;
  t.first.push_back(0);
  for (int i = 0; i < fb.pixels; ++i) {
    const double xd = fb.pixel_x(i), zd = fb.pixel_z(i);
    const double slope = (fb.source_x_mm - xd) / (fb.source_z_mm - zd);
    t.xd.push_back(xd), t.zd.push_back(zd), t.slope.push_back(slope);
    t.sec.push_back(std::sqrt(1 + slope * slope));
    auto x_at = [&](double z) { return xd + slope * (z - zd); };
    // The walk of ray_path_length with the top at z_max, recording the cells instead of
    // sampling them.
    double z = 0;
    for (int guard = 0; guard < n + 4 && z < z_max_mm; ++guard) {
      const auto [cell, step_exit] = ray_step(z, xd, zd, slope, t.x0_mm, t.pitch_mm, z_max_mm);
      double zexit = step_exit;
      if ((cell < -1 && slope <= 0) || (cell >= n && slope >= 0)) break;
      if (zexit - z > kMinRaySegmentMm && cell >= -1 && cell < n) {
        const double xc = t.x0_mm + cell * t.pitch_mm;
        t.seg.push_back(
            {cell, z, zexit, (x_at(z) - xc) / t.pitch_mm, (x_at(zexit) - xc) / t.pitch_mm});
      }
      if (zexit <= z) zexit = z + 1e-9;
      z = zexit;
    }
    t.first.push_back(int32_t(t.seg.size()));
  }
  return t;
}

void project_line(const RayTable& t, const float* h, const uint8_t* hv, float* thickness,
                  uint8_t* thickness_valid) {
  const int n = t.grid_n;
  float top = 0;
  for (int g = 0; g < n; ++g)
    if (hv[g]) top = std::max(top, h[g]);
  const double ztop = std::max<double>(top, 1e-6);
  if (ztop > t.z_max_mm) {  // above the table: the walk
    const ProfileGrid grid{h, hv, n, t.x0_mm, t.pitch_mm, top};
    for (int i = 0; i < t.pixels; ++i) {
      const PathResult r =
          ray_path_length(grid, t.xd[i], t.zd[i], t.beam.source_x_mm, t.beam.source_z_mm);
      thickness[i] = r.valid ? float(r.length_mm) : kNaN;
      thickness_valid[i] = r.valid;
    }
    return;
  }
  // Most rays cross no meat: where every sample a ray's cells could read (a cell's margin
  // either way) is valid and at or below the belt, its path is 0 without the walk (the walk
  // adds nothing there: h - z <= 0 in every cell).
  thread_local std::vector<int32_t> meat_or_invalid;
  meat_or_invalid.resize(size_t(n) + 1);
  meat_or_invalid[0] = 0;
  for (int g = 0; g < n; ++g) meat_or_invalid[g + 1] = meat_or_invalid[g] + (!hv[g] || h[g] > 0);
  for (int i = 0; i < t.pixels; ++i) {
    const double c0 = (t.xd[i] + t.slope[i] * (0 - t.zd[i]) - t.x0_mm) / t.pitch_mm,
                 c1 = (t.xd[i] + t.slope[i] * (ztop - t.zd[i]) - t.x0_mm) / t.pitch_mm;
    const int lo = std::clamp(int(std::floor(std::min(c0, c1))) - 1, 0, n),
              hi = std::clamp(int(std::floor(std::max(c0, c1))) + 3, 0, n);
    if (meat_or_invalid[hi] == meat_or_invalid[lo]) {
      thickness[i] = 0.f;
      thickness_valid[i] = 1;
      continue;
    }
    bool valid = true;
    auto sample = [&](int k) -> double {
      if (k < 0 || k >= n) return 0.0;
      if (!hv[k]) {
        valid = false;
        return 0.0;
      }
      return h[k];
    };
    double len = 0;
    for (int s = t.first[i]; s < t.first[i + 1]; ++s) {
      const RaySegment& g = t.seg[s];
      if (g.z0 >= ztop) break;
      double z1 = g.z1, t1 = g.t1;
      if (z1 > ztop) {  // the walk's last cell ends at the top
        z1 = ztop;
        if (!(z1 - g.z0 > kMinRaySegmentMm)) break;
        t1 = (t.xd[i] + t.slope[i] * (z1 - t.zd[i]) - (t.x0_mm + g.cell * t.pitch_mm)) / t.pitch_mm;
      }
      const double h0 = sample(g.cell), h1 = sample(g.cell + 1);
      len += positive_span(g.z0, z1, h0 + (h1 - h0) * g.t0 - g.z0, h0 + (h1 - h0) * t1 - z1);
    }
    thickness[i] = valid ? float(len * t.sec[i]) : kNaN;
    thickness_valid[i] = valid;
  }
}

}  // namespace rangex
