#include "pipeline/profile_fusion.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/no_value.h"

namespace rangex {

namespace {

// Resamples one camera's column polyline onto the grid (NaN where it has no data).
void resample_camera(const float* x, const float* z, const uint8_t* valid, int width,
                     const FusionParams& p, int grid_n, float* grid) {
  std::fill(grid, grid + grid_n, kNaN);
  const double inv = 1.0 / p.grid_pitch_mm;
  for (int c = 0; c + 1 < width; ++c) {
    if (!valid[c] || !valid[c + 1]) continue;
    const double xa = x[c], xb = x[c + 1];
    if (std::abs(xb - xa) > p.max_column_step_mm || xa == xb) continue;
    const double lo = std::min(xa, xb), hi = std::max(xa, xb);
    const int g0 = std::max(0, int(std::ceil((lo - p.grid_x0_mm) * inv)));
    const int g1 = std::min(grid_n - 1, int(std::floor((hi - p.grid_x0_mm) * inv)));
    for (int g = g0; g <= g1; ++g) {
      const double xg = p.grid_x0_mm + g * p.grid_pitch_mm;
      const double t = (xg - xa) / (xb - xa);
      const float zg = float(z[c] + t * (z[c + 1] - z[c]));
      grid[g] = std::isnan(grid[g]) ? zg : std::max(grid[g], zg);
    }
  }
}
}  // namespace

void fuse_profiles(const float* x, const float* z, const uint8_t* valid, int width, int lines,
                   const int* lane_slot, const FusionParams* params, int grid_n, float* profile,
                   uint8_t* profile_valid, FusionStats* stats) {
  std::vector<float> a(grid_n), b(grid_n);
  FusionStats st;
  for (int l = 0; l < lines; ++l) {
    const FusionParams& p = params[lane_slot[l]];
    const size_t f0 = size_t(l) * 2 * width, f1 = f0 + width;
    resample_camera(x + f0, z + f0, valid + f0, width, p, grid_n, a.data());
    resample_camera(x + f1, z + f1, valid + f1, width, p, grid_n, b.data());
    float* out = profile + size_t(l) * grid_n;
    uint8_t* ov = profile_valid + size_t(l) * grid_n;
    for (int g = 0; g < grid_n; ++g) {
      const bool va = !std::isnan(a[g]), vb = !std::isnan(b[g]);
      if (va && vb) {
        if (std::abs(a[g] - b[g]) <= p.agree_tol_mm) {
          out[g] = 0.5f * (a[g] + b[g]);
          ov[g] = 1;
          ++st.both;
        } else {
          out[g] = kNaN;
          ov[g] = 0;
          ++st.conflict;
        }
      } else if (va || vb) {
        out[g] = va ? a[g] : b[g];
        ov[g] = 1;
        ++st.single;
      } else {
        out[g] = kNaN;
        ov[g] = 0;
      }
    }
    // Short gaps between valid samples are interpolated; longer ones stay invalid.
    const int max_gap = int(std::floor(p.max_gap_mm / p.grid_pitch_mm + 1e-9));
    int last = -1;
    for (int g = 0; g < grid_n; ++g) {
      if (!ov[g]) continue;
      const int gap = g - last - 1;
      if (last >= 0 && gap > 0 && gap <= max_gap) {
        for (int k = last + 1; k < g; ++k) {
          const float t = float(k - last) / float(g - last);
          out[k] = out[last] + t * (out[g] - out[last]);
          ov[k] = 1;
          ++st.filled;
        }
      }
      last = g;
    }
    for (int g = 0; g < grid_n; ++g) st.missing += ov[g] ? 0 : 1;
  }
  if (stats) *stats += st;
}

}  // namespace rangex
