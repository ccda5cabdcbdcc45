#include "pipeline/fan_projection.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/ray_path.h"

namespace rangex {

void project_fan_beam(const float* profile, const uint8_t* profile_valid, int lines, int grid_n,
                      const int* lane_slot, const FusionParams* grids, const FanBeam* beams,
                      int pixels, float* thickness, uint8_t* thickness_valid) {
  for (int l = 0; l < lines; ++l) {
    const FusionParams& gp = grids[lane_slot[l]];
    const FanBeam& fb = beams[lane_slot[l]];
    const float* h = profile + size_t(l) * grid_n;
    const uint8_t* hv = profile_valid + size_t(l) * grid_n;
    float top = 0;
    for (int g = 0; g < grid_n; ++g)
      if (hv[g]) top = std::max(top, h[g]);
    // Samples below the belt (noise) must not make negative meat.
    const ProfileGrid grid{h, hv, grid_n, gp.grid_x0_mm, gp.grid_pitch_mm, top};
    const double px = fb.pitch_x(), pz = fb.pitch_z();
    for (int i = 0; i < pixels; ++i) {
      const PathResult r =
          ray_path_length(grid, fb.first_pixel_x_mm + px * i, fb.detector_z_mm + pz * i,
                          fb.source_x_mm, fb.source_z_mm);
      const size_t o = size_t(l) * pixels + i;
      thickness[o] = r.valid ? float(r.length_mm) : std::numeric_limits<float>::quiet_NaN();
      thickness_valid[o] = r.valid ? 1 : 0;
    }
  }
}

}  // namespace rangex
