// The pseudo-X-ray made to match the detector: a domed fillet with a vertical
// wall (20 mm of meat within one pixel), seen by an X-ray whose detector blurs (Gaussian line
// spread) and whose plane lies a fraction of a line off and turned against the laser's.
// Compared with the truth rendered here, not with the code under test.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "pipeline/detector_match.h"
#include "pipeline/inspection.h"
#include "sim/rng.h"

namespace rangex {
namespace {

constexpr double kMu = 0.03, kB0 = std::log(3600.0);

struct Scene {
  double cx = 0, cy = 140, radius = 25, height = 20;  // a domed disc: 20 mm walls, mm
  double bone_x = 1e9, bone_y = 0, bone_r = 1.5, bone_att = 0.08;
  double thickness(double x, double y) const {
    const double rho = std::hypot(x - cx, y - cy) / radius;
    return rho < 1 ? height + 10 * (1 - rho * rho) : 0.0;
  }
};

// rows x cols of 0.4 mm; x0 = -32 mm, y0 = 100 mm; parallel beam. The image's thickness is
// the laser's (row r sees y0 + 0.4 r); the X-ray sees row r - shift - x tan(alpha) / 0.4,
// integrates the belt's travel over the line, and blurs across the detector by sigma_px
// (and over each pixel's aperture).
FilletImage render(const Scene& s, double shift, double tan_alpha, double sigma_px, uint64_t seed) {
  FilletImage f;
  f.rows = 200, f.cols = 160;
  f.x0_mm = -32, f.y0_mm = 100, f.pitch_mm = f.step_mm = 0.4;
  f.source_z_mm = 1e9;
  f.xray.resize(f.size());
  f.thickness.resize(f.size());
  f.mask.resize(f.size());
  sim::Rng rng(seed);
  constexpr int kSub = 8;
  std::vector<double> fine(size_t(f.cols) * kSub);
  for (int r = 0; r < f.rows; ++r) {
    for (int c = 0; c < f.cols; ++c) {
      const double x = f.x0_mm + 0.4 * c, t = s.thickness(x, f.y0_mm + 0.4 * r);
      f.thickness[size_t(r) * f.cols + c] = float(t);
      f.mask[size_t(r) * f.cols + c] = t > 1.5;
    }
    for (int k = 0; k < f.cols * kSub; ++k) {
      const double u = (k + 0.5) / kSub - 0.5, x = f.x0_mm + 0.4 * u;
      fine[k] = 0;
      for (int j = 0; j < kSub; ++j) {
        const double travel = (j + 0.5) / kSub - 0.5;
        const double y = f.y0_mm + 0.4 * (r + travel - shift - x * tan_alpha / 0.4);
        double ln = kB0 - kMu * s.thickness(x, y);
        const double d2 =
            (std::pow(x - s.bone_x, 2) + std::pow(y - s.bone_y, 2)) / (s.bone_r * s.bone_r);
        if (d2 < 1) ln -= s.bone_att * std::sqrt(1 - d2);
        fine[k] += std::exp(ln) / kSub;
      }
    }
    const double sf = sigma_px * kSub;
    const int R = int(std::ceil(4 * sf));
    for (int c = 0; c < f.cols; ++c) {
      double sum = 0, w = 0;
      for (int k = c * kSub; k < (c + 1) * kSub; ++k)
        for (int j = -R; j <= R; ++j) {
          const double g = sf > 0 ? std::exp(-0.5 * j * j / (sf * sf)) : (j == 0);
          sum += g * fine[std::clamp(k + j, 0, f.cols * kSub - 1)], w += g;
        }
      const double photons = sum / w * 10;
      const double dn = (photons + std::sqrt(photons) * rng.normal()) / 10 + 2 * rng.normal();
      f.xray[size_t(r) * f.cols + c] = uint16_t(std::clamp(std::lround(dn), 1L, 4095L));
    }
  }
  return f;
}

// RMS of the residual ln I - ln P within 2 mm of the wall, through the fillet's own fit.
double edge_rms(const FilletImage& img, const Scene& s, const FilletResult& r) {
  EXPECT_EQ(r.residual.size(), img.size()) << "not inspected: " << r.reason;
  if (r.residual.size() != img.size()) return NAN;
  double ss = 0;
  int n = 0;
  for (int row = 0; row < img.rows; ++row)
    for (int c = 0; c < img.cols; ++c) {
      const size_t i = size_t(row) * img.cols + c;
      const double d = std::hypot(img.x0_mm + 0.4 * c - s.cx, img.y0_mm + 0.4 * row - s.cy);
      if (std::abs(d - s.radius) < 2 && std::isfinite(r.residual[i]))
        ss += double(r.residual[i]) * r.residual[i], ++n;
    }
  return std::sqrt(ss / std::max(1, n));
}

constexpr double kShift = 0.4, kTanAlpha = 0.006, kSigma = 1.0;

FilletImage with_detector(FilletImage f) {
  f.shift_lines = kShift, f.tan_alpha = kTanAlpha, f.detector_sigma_px = kSigma;
  return f;
}

TEST(DetectorMatch, ABlurredWallCancelsAndIsNotBone) {
  const Scene s;
  const FilletImage plain = render(s, kShift, kTanAlpha, kSigma, 3);
  InspectionParams p;
  const FilletResult without = inspect_fillet(plain, p, true);
  const FilletResult with = inspect_fillet(with_detector(plain), p, true);
  const double e0 = edge_rms(plain, s, without), e1 = edge_rms(plain, s, with);
  std::printf(
      "wall residual RMS (ln): thickness as measured %.4f, matched to the detector %.4f;"
      " fragments %zu / %zu; gradient term c %.3f px^2\n",
      e0, e1, without.fragments.size(), with.fragments.size(), with.noise.c);
  for (const Blob& b : with.fragments)
    std::printf("  fragment at %.1f, %.1f mm (%.2f mm from the wall), area %.2f mm2, peak z %.1f\n",
                b.x_mm, b.y_mm, std::hypot(b.x_mm - s.cx, b.y_mm - s.cy) - s.radius, b.area_mm2,
                b.peak_z);
  EXPECT_LT(e1, 0.5 * e0);
  EXPECT_EQ(with.decision, Decision::kPass) << with.reason;
  EXPECT_TRUE(with.fragments.empty());
}

TEST(DetectorMatch, ABoneAtTheWallIsStillFound) {
  Scene s;
  s.bone_x = s.cx + s.radius - 2.5, s.bone_y = s.cy;  // 2.5 mm inside the wall
  const FilletImage img = with_detector(render(s, kShift, kTanAlpha, kSigma, 4));
  const FilletResult r = inspect_fillet(img, InspectionParams{}, false);
  ASSERT_EQ(r.decision, Decision::kReject) << r.reason;
  double best = 1e9;
  for (const Blob& b : r.fragments)
    best = std::min(best, std::hypot(b.x_mm - s.bone_x, b.y_mm - s.bone_y));
  std::printf("bone 2.5 mm inside the wall found %.2f mm from where it is\n", best);
  EXPECT_LT(best, 1.0);
}

TEST(DetectorMatch, ShiftAndBlurFollowTheirDefinitions) {
  // A thickness ramp along the rows: shifting by 0.25 row reads a quarter row back (in
  // transmission).
  FilletImage f;
  f.rows = 10, f.cols = 30;
  f.x0_mm = 0, f.pitch_mm = f.step_mm = 0.4;
  f.source_z_mm = 1e9;
  f.thickness.resize(f.size());
  for (int r = 0; r < f.rows; ++r)
    for (int c = 0; c < f.cols; ++c) f.thickness[size_t(r) * f.cols + c] = float(r);
  f.shift_lines = 0.25;
  FilletImage g = f;
  match_detector(g, kMu);
  EXPECT_NEAR(g.thickness[5 * f.cols + 7],
              -std::log(0.75 * std::exp(-kMu * 5) + 0.25 * std::exp(-kMu * 4)) / kMu, 1e-4);
  // A step across the columns under a 1 px blur: the mean of exp(-mu T) under the Gaussian.
  FilletImage h = f;
  h.shift_lines = 0, h.detector_sigma_px = 1.0;
  for (int r = 0; r < h.rows; ++r)
    for (int c = 0; c < h.cols; ++c) h.thickness[size_t(r) * h.cols + c] = c < 15 ? 0.f : 20.f;
  match_detector(h, kMu);
  double sw = 0, se = 0;
  for (int k = 0; k < h.cols; ++k) {
    const double w = std::exp(-0.5 * (k - 15) * (k - 15));
    if (std::abs(k - 15) <= 4) sw += w, se += w * std::exp(-kMu * (k < 15 ? 0 : 20));
  }
  EXPECT_NEAR(h.thickness[2 * h.cols + 15], -std::log(se / sw) / kMu, 1e-4);
  EXPECT_NEAR(h.thickness[2 * h.cols + 2], 0, 1e-6);
}

}  // namespace
}  // namespace rangex
