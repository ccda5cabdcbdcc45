#include "pipeline/test_pieces.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace rangex {

namespace {

// Chord length of a vertical ray through the piece at object offset (dx, dy) from its centre.
double chord(const TestPiece& p, double dx, double dy, double needle_d) {
  if (p.shape == TestPiece::kSphere) {
    const double r = 0.5 * p.size_mm, q = r * r - dx * dx - dy * dy;
    return q > 0 ? 2 * std::sqrt(q) : 0.0;
  }
  const double c = std::cos(p.angle_rad), s = std::sin(p.angle_rad);
  const double along = dx * c + dy * s, across = -dx * s + dy * c;
  // A cylinder with hemispherical ends.
  const double half = std::max(0.0, 0.5 * p.size_mm - 0.5 * needle_d);
  const double a = std::max(0.0, std::abs(along) - half);
  const double r = 0.5 * needle_d, q = r * r - a * a - across * across;
  return q > 0 ? 2 * std::sqrt(q) : 0.0;
}

void inject_layer(FilletImage& img, const TestPiece& p, double dmu, double needle_d,
                  std::vector<uint16_t>& counts);

}  // namespace

void inject_test_piece(FilletImage& img, const TestPiece& p, double meat_mu,
                       const TestPieceMaterial& m, double high_excess) {
  const double dmu = m.excess(meat_mu);
  if (!(dmu > 0)) return;
  // One pass per line it attenuates: the low (or only) line, and a dual-energy high line.
  const bool high = high_excess > 0 && img.xray_high.size() == img.size();
  for (int layer = 0; layer < (high ? 2 : 1); ++layer)
    inject_layer(img, p, layer == 0 ? dmu : high_excess, m.needle_diameter_mm,
                 layer == 0 ? img.xray : img.xray_high);
}

namespace {
void inject_layer(FilletImage& img, const TestPiece& p, double dmu, double needle_d,
                  std::vector<uint16_t>& counts) {
  // The fan beam magnifies across the belt by (zs - zd) / (zs - h); along the belt a line
  // scan does not magnify.
  const double mag = (img.source_z_mm - img.detector_z_mm) / (img.source_z_mm - p.height_mm);
  const double reach = 0.5 * p.size_mm + 1;
  const int rr = int(std::ceil(reach / img.step_mm)) + 1;
  const int blur_px = 4;
  const int rc = int(std::ceil(reach * mag / img.pitch_mm)) + 1 + blur_px;
  const int r0 = std::max(0, p.row - rr), r1 = std::min(img.rows - 1, p.row + rr);
  const int c0 = std::max(0, p.col - rc), c1 = std::min(img.cols - 1, p.col + rc);
  if (r0 > r1 || c0 > c1) return;
  const int W = c1 - c0 + 1;
  // The blur across the detector: line spread and the focal spot's image at this height.
  const double focal_px = img.focal_spot_sigma_mm * (p.height_mm - img.detector_z_mm) /
                          (img.source_z_mm - p.height_mm) / img.pitch_mm;
  const double sigma = std::hypot(img.detector_sigma_px, focal_px);
  constexpr int kSub = 4;
  std::vector<double> trans(static_cast<size_t>(W)), blurred(static_cast<size_t>(W));
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      double t = 0;
      for (int i = 0; i < kSub; ++i)
        for (int j = 0; j < kSub; ++j) {
          const double dy = (r - p.row + (i + 0.5) / kSub - 0.5) * img.step_mm;
          const double dx_det = (c - p.col + (j + 0.5) / kSub - 0.5) * img.pitch_mm;
          t += std::exp(-dmu * chord(p, dx_det / mag, dy, needle_d));
        }
      trans[size_t(c - c0)] = t / (kSub * kSub);
    }
    // The detector blurs intensities: the transmission, not the attenuation.
    if (sigma > 0.05) {
      const int R = std::min(blur_px, int(std::ceil(3 * sigma)));
      for (int c = 0; c < W; ++c) {
        double sum = 0, wsum = 0;
        for (int k = -R; k <= R; ++k) {
          const int q = std::clamp(c + k, 0, W - 1);
          const double w = std::exp(-0.5 * k * k / (sigma * sigma));
          sum += w * trans[size_t(q)], wsum += w;
        }
        blurred[size_t(c)] = sum / wsum;
      }
    } else {
      blurred = trans;
    }
    for (int c = c0; c <= c1; ++c) {
      uint16_t& v = counts[size_t(r) * img.cols + c];
      v = uint16_t(std::lround(v * blurred[size_t(c - c0)]));
    }
  }
}

}  // namespace

}  // namespace rangex
