// The bilinear rectification table against the exact model, everywhere on the sensor.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/lane_config.h"
#include "pipeline/rectify_table.h"

using namespace rangex;

namespace {
// Pixel-equivalent error: the table's (x, z) put back on the laser plane and projected with
// the exact camera model, compared with the pixel it came from.
double worst_error_px(const LaneCamera& cam, const LaserPlane& plane, int step, int samples) {
  const RectifyTable t = build_rectify_table(cam.model, plane, step);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uv(0, cam.model.height() - 1);
  const int W = cam.model.width();
  std::vector<float> row(W), x(W), z(W);
  std::vector<uint8_t> valid(W, 1), ov(W);
  const int slot = 0;
  double worst = 0;
  for (int s = 0; s < samples / W; ++s) {
    for (int c = 0; c < W; ++c) row[c] = float(uv(rng));
    rectify(row.data(), valid.data(), 1, W, &slot, &t, x.data(), z.data(), ov.data());
    for (int c = 0; c < W; ++c) {
      // The point on the plane with this (x, z).
      const double y =
          (plane.offset_mm - plane.normal.x * x[c] - plane.normal.z * z[c]) / plane.normal.y;
      const Vec2 p = cam.model.project({x[c], y, z[c]});
      worst = std::max(worst, std::hypot(p.x - c, p.y - row[c]));
    }
  }
  return worst;
}
}  // namespace

TEST(RectifyTable, WithinOneHundredthPixelEverywhere) {
  const LaneConfig lc = default_lane_config(0);
  for (int cam = 0; cam < 2; ++cam) {
    const double worst = worst_error_px(lc.cameras[cam], lc.laser, lc.lut_step_px, 640 * 400);
    RecordProperty("worst_px_cam" + std::to_string(cam), std::to_string(worst));
    std::printf("camera %d, table step %d px: worst error %.5f px\n", cam, lc.lut_step_px, worst);
    EXPECT_LE(worst, 0.01) << "camera " << cam;
  }
}

TEST(RectifyTable, TiltedLaserPlane) {
  LaneConfig lc = default_lane_config(0);
  lc.laser.normal = Vec3{0.02, 1, -0.03}.normalized();
  lc.laser.offset_mm = 1.5;
  for (int cam = 0; cam < 2; ++cam)
    EXPECT_LE(worst_error_px(lc.cameras[cam], lc.laser, lc.lut_step_px, 640 * 100), 0.01);
}

TEST(RectifyTable, ExactPointLiesOnPlaneAndRay) {
  const LaneConfig lc = default_lane_config(0);
  double x, z;
  ASSERT_TRUE(exact_plane_point(lc.cameras[0].model, lc.laser, 320, 100, x, z));
  const Vec2 p = lc.cameras[0].model.project({x, 0, z});
  EXPECT_NEAR(p.x, 320, 1e-9);
  EXPECT_NEAR(p.y, 100, 1e-9);
}
