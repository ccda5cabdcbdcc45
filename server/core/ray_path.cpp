#include "core/ray_path.h"

#include <algorithm>
#include <cmath>

namespace rangex {

double positive_span(double a, double b, double fa, double fb) {
  if (fa <= 0 && fb <= 0) return 0;
  if (fa >= 0 && fb >= 0) return b - a;
  const double root = a + (b - a) * fa / (fa - fb);
  return fa > 0 ? root - a : b - root;
}

RayStep ray_step(double z, double xd, double zd, double slope, double x0_mm, double pitch_mm,
                 double ztop) {
  const double x = xd + slope * (z - zd);
  const double fc = (x - x0_mm) / pitch_mm;
  int cell = static_cast<int>(std::floor(fc));
  // On a boundary moving left, the cell is the one to the left.
  if (slope < 0 && fc == std::floor(fc)) cell -= 1;
  double zexit = ztop;
  if (slope > 0) {
    const double xb = x0_mm + (cell + 1) * pitch_mm;
    zexit = std::min(ztop, zd + (xb - xd) / slope);
  } else if (slope < 0) {
    const double xb = x0_mm + cell * pitch_mm;
    zexit = std::min(ztop, zd + (xb - xd) / slope);
  }
  return {cell, zexit};
}

PathResult ray_path_length(const ProfileGrid& g, double xd, double zd, double xs, double zs) {
  PathResult out;
  const double zspan = zs - zd;
  const double slope = (xs - xd) / zspan;  // dx/dz along the ray
  const double sec = std::sqrt(1 + slope * slope);
  // At least the cell under the ray's foot is visited, so that its validity is checked.
  const double ztop = std::max<double>(g.max_height_mm, 1e-6);
  auto x_at = [&](double z) { return xd + slope * (z - zd); };
  auto sample = [&](int i) -> double {
    if (i < 0 || i >= g.n) return 0.0;
    if (g.valid && !g.valid[i]) {
      out.valid = false;
      return 0.0;
    }
    return g.height[i];
  };

  double z = 0;
  double len = 0;
  // Walk the cells the ray crosses between the belt and the highest sample.
  for (int guard = 0; guard < g.n + 4 && z < ztop; ++guard) {
    const auto [cell, step_exit] = ray_step(z, xd, zd, slope, g.x0_mm, g.pitch_mm, ztop);
    double zexit = step_exit;
    if (cell < -1 || cell >= g.n) {
      // Outside the grid there is no meat; keep walking only if the ray can come back.
      if ((cell < -1 && slope <= 0) || (cell >= g.n && slope >= 0)) break;
    }
    // A step of no length (whether the walk takes one depends on the last bit of a double)
    // only crosses a cell boundary: there is no meat in it to sample.
    if (zexit - z > kMinRaySegmentMm) {
      const double h0 = sample(cell), h1 = sample(cell + 1);
      const double x_cell = g.x0_mm + cell * g.pitch_mm;  // (a lambda may not name a binding)
      auto h_at = [&](double zz) {
        const double t = (x_at(zz) - x_cell) / g.pitch_mm;
        return h0 + (h1 - h0) * t;
      };
      len += positive_span(z, zexit, h_at(z) - z, h_at(zexit) - zexit);
    }
    if (zexit <= z) zexit = z + 1e-9;  // numerical guard: always advance
    z = zexit;
  }
  out.length_mm = len * sec;
  return out;
}

}  // namespace rangex
