#include "sim/synthetic_fillet.h"

#include <algorithm>
#include <cmath>

#include "sim/rng.h"

namespace rangex::sim {

FilletImage synthetic_fillet(double b0, double b1, const std::vector<PlantedBone>& bones,
                             uint64_t seed, int rows, int cols, double hardening) {
  FilletImage f;
  f.rows = rows;
  f.cols = cols;
  f.x0_mm = -40;
  f.y0_mm = 100;
  f.source_z_mm = 1e9;
  f.xray.resize(f.size());
  f.thickness.resize(f.size());
  f.mask.resize(f.size());
  Rng rng(seed);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const size_t i = size_t(r) * cols + c;
      const double u = (r - rows / 2.0) / (rows / 2.0 - 4), v = (c - cols / 2.0) / (cols / 2.0 - 4);
      const double rho2 = u * u + v * v;
      const double t = rho2 < 1 ? 40 * (1 - rho2) : 0.0;
      f.thickness[i] = float(t);
      f.mask[i] = t > 1.5;
      const double a = -b1 * t;
      double ln = hardening > 0 ? b0 - a / (1 + hardening * a) : b0 + b1 * t;
      const double x = f.x0_mm + 0.4 * c, y = f.y0_mm + 0.4 * r;
      for (const PlantedBone& b : bones) {
        const double d2 = ((x - b.x_mm) * (x - b.x_mm) + (y - b.y_mm) * (y - b.y_mm)) /
                          (b.radius_mm * b.radius_mm);
        if (d2 < 1) ln -= b.attenuation * std::sqrt(1 - d2);
      }
      const double photons = std::exp(ln) * 10;
      const double dn = (photons + std::sqrt(photons) * rng.normal()) / 10 + 2 * rng.normal();
      f.xray[i] = uint16_t(std::clamp(std::lround(dn), 1L, 4095L));
    }
  return f;
}

}  // namespace rangex::sim
