// Two-camera fusion rules: agree -> mean, one -> the other, conflict -> invalid, short gaps
// interpolated, long gaps left invalid.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "pipeline/profile_fusion.h"

using namespace rangex;

namespace {
constexpr int W = 200;

struct Cams {
  std::vector<float> x = std::vector<float>(2 * W), z = std::vector<float>(2 * W);
  std::vector<uint8_t> v = std::vector<uint8_t>(2 * W, 1);
  // Both cameras see x = -20 .. +19.8 (0.2 mm per column) at heights f0, f1.
  template <typename F0, typename F1>
  Cams(F0 f0, F1 f1) {
    for (int c = 0; c < W; ++c) {
      x[c] = x[W + c] = float(-20 + 0.2 * c);
      z[c] = float(f0(x[c]));
      z[W + c] = float(f1(x[c]));
    }
  }
};

FusionParams grid() {
  FusionParams p;
  p.grid_x0_mm = -10;
  p.grid_pitch_mm = 0.1;
  p.grid_samples = 201;  // -10 .. +10
  p.agree_tol_mm = 1.0;
  p.max_gap_mm = 3.0;
  return p;
}

void fuse(const Cams& c, std::vector<float>& out, std::vector<uint8_t>& ov,
          FusionStats* st = nullptr) {
  const FusionParams p = grid();
  out.resize(p.grid_samples);
  ov.resize(p.grid_samples);
  const int slot = 0;
  fuse_profiles(c.x.data(), c.z.data(), c.v.data(), W, 1, &slot, &p, p.grid_samples, out.data(),
                ov.data(), st);
}
}  // namespace

TEST(ProfileFusion, AgreeingCamerasAreAveraged) {
  Cams c([](double x) { return 10 + 0.1 * x; }, [](double x) { return 10.4 + 0.1 * x; });
  std::vector<float> out;
  std::vector<uint8_t> ov;
  fuse(c, out, ov);
  for (int g = 0; g < 201; ++g) {
    ASSERT_TRUE(ov[g]);
    EXPECT_NEAR(out[g], 10.2 + 0.1 * (-10 + 0.1 * g), 1e-4);
  }
}

TEST(ProfileFusion, OccludedCameraFallsBackToTheOther) {
  Cams c([](double) { return 5.0; }, [](double) { return 5.2; });
  for (int col = 80; col < 120; ++col) c.v[col] = 0;  // camera 0 occluded around x = 0
  std::vector<float> out;
  std::vector<uint8_t> ov;
  fuse(c, out, ov);
  EXPECT_NEAR(out[100], 5.2, 1e-5);  // x = 0: camera 1 only
  EXPECT_NEAR(out[0], 5.1, 1e-5);    // x = -10: both
}

TEST(ProfileFusion, ConflictIsInvalidNotAveraged) {
  Cams c([](double) { return 5.0; }, [](double x) { return std::abs(x) < 1 ? 9.0 : 5.0; });
  std::vector<float> out;
  std::vector<uint8_t> ov;
  FusionStats st;
  // Gap filling would bridge the conflict; keep it visible by making it longer than max_gap.
  for (int col = 0; col < W; ++col) {
    const double x = -20 + 0.2 * col;
    if (std::abs(x) < 2.5) c.z[W + col] = 9.0f;
  }
  fuse(c, out, ov, &st);
  EXPECT_FALSE(ov[100]);
  EXPECT_TRUE(std::isnan(out[100]));
  EXPECT_GT(st.conflict, 0);
}

TEST(ProfileFusion, ShortGapsInterpolatedLongGapsStayInvalid) {
  Cams c([](double x) { return 2 * x + 30; }, [](double x) { return 2 * x + 30; });
  // Both cameras blind over a 2 mm gap at x in (-6, -4) and a 5 mm gap at x in (2, 7).
  for (int col = 0; col < W; ++col) {
    const double x = -20 + 0.2 * col;
    if ((x > -6 && x < -4) || (x > 2 && x < 7)) c.v[col] = c.v[W + col] = 0;
  }
  std::vector<float> out;
  std::vector<uint8_t> ov;
  fuse(c, out, ov);
  ASSERT_TRUE(ov[50]);  // x = -5: inside the short gap
  EXPECT_NEAR(out[50], 20.0, 1e-3);
  EXPECT_FALSE(ov[145]);  // x = 4.5: inside the long gap
}
