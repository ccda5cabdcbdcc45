#include "pipeline/detector_match.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/no_value.h"

namespace rangex {

void match_detector(FilletImage& img, double mu) {
  if (!img.matches_detector() || img.rows <= 0 || img.cols <= 0) return;
  const int R = img.rows, C = img.cols;
  const std::vector<float>& T = img.thickness;
  // Work in transmission, exp(-mu T): the detector averages intensities.
  std::vector<double> e(T.size());
  for (size_t i = 0; i < T.size(); ++i) e[i] = std::isfinite(T[i]) ? std::exp(-mu * T[i]) : NAN;
  // x (mm) of a column's ray where it is z above the belt.
  const double zd = img.detector_z_mm;
  auto ray_x = [&](int c, double z) {
    const double xd = img.x0_mm + img.pitch_mm * c;
    return xd + (img.source_x_mm - xd) * (z - zd) / (img.source_z_mm - zd);
  };
  // 1. Along the belt: the X-ray line integrates the belt's travel over one line; the line
  // it saw at (row, column) lies `d` rows before the row's laser line. Linear interpolation
  // of the transmission between rows is the average over a line's travel.
  std::vector<double> S(T.size(), NAN);
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < C; ++c) {
      const float t0 = T[size_t(r) * C + c];
      const double z = std::isfinite(t0) ? 0.5 * t0 : 0.0;
      const double d =
          img.shift_lines + (ray_x(c, z) * img.tan_alpha + z * img.tan_beta) / img.step_mm;
      const double src = std::clamp(double(r) - d, 0.0, double(R - 1));
      const int r0 = std::min(int(src), std::max(0, R - 2)), r1 = std::min(r0 + 1, R - 1);
      const double f = src - r0;
      const double a = e[size_t(r0) * C + c], b = e[size_t(r1) * C + c];
      S[size_t(r) * C + c] = std::isnan(a)   ? (f > 0.5 ? b : NAN)
                             : std::isnan(b) ? (f < 0.5 ? a : NAN)
                                             : (1 - f) * a + f * b;
    }
  // 2. Across the detector: the line-spread function and the focal spot's image (which
  // grows with height), Gaussian, over the transmission.
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < C; ++c) {
      const size_t o = size_t(r) * C + c;
      if (std::isnan(S[o]) || !std::isfinite(T[o])) {
        img.thickness[o] = kNaN;
        continue;
      }
      const double z = 0.5 * T[o];
      const double focal =
          img.focal_spot_sigma_mm * (z - zd) / (img.source_z_mm - z) / img.pitch_mm;
      const double sigma = std::hypot(img.detector_sigma_px, focal);
      double blurred = S[o];
      if (sigma >= 0.05) {
        const int reach = int(std::ceil(3.5 * sigma));
        double sw = 0, se = 0;
        for (int k = std::max(0, c - reach); k <= std::min(C - 1, c + reach); ++k) {
          const double v = S[size_t(r) * C + k];
          if (std::isnan(v)) continue;
          const double w = std::exp(-0.5 * (k - c) * (k - c) / (sigma * sigma));
          sw += w, se += w * v;
        }
        blurred = se / sw;
      }
      img.thickness[o] = float(-std::log(blurred) / mu);
    }
}

}  // namespace rangex
