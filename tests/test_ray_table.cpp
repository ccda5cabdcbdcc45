// The ray tables give the walk's path lengths (core/ray_path.cpp) bit for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/lane_config.h"
#include "pipeline/fan_projection.h"
#include "pipeline/ray_table.h"

using namespace rangex;

namespace {

// A line of fillet-like heights: domes, a steep wall, invalid samples, noise below the belt.
void make_profile(std::mt19937& rng, int n, double peak, bool below, std::vector<float>& h,
                  std::vector<uint8_t>& v) {
  std::uniform_real_distribution<double> u(0, 1);
  h.assign(n, 0.f);
  v.assign(n, 1);
  const int c0 = int(n * (0.2 + 0.3 * u(rng))), w = int(n * (0.1 + 0.2 * u(rng)));
  for (int g = 0; g < n; ++g) {
    const double d = double(g - c0) / w;
    // Off the fillet: belt noise either way, or (every other line) only below the belt.
    const double noise = below ? -0.05 * u(rng) : 0.05 * (u(rng) - 0.5);
    h[g] = float(std::abs(d) < 1 ? peak * (1 - d * d) : noise);
  }
  const int wall = c0 + w / 2;  // a wall: full height to nothing in one sample
  for (int g = wall; g < std::min(n, wall + 3); ++g) h[g] = 0;
  for (int k = 0; k < 6; ++k)
    if (u(rng) < 0.5) v[int(u(rng) * n)] = 0;
}

}  // namespace

TEST(RayTable, EqualsTheWalkBitForBit) {
  LaneConfig lane = default_lane_config(0);
  for (double tilt : {0.0, 1.5}) {
    lane.xray.tilt_deg = tilt;
    const int n = lane.fusion.grid_samples, P = lane.xray.pixels;
    const RayTable table = build_ray_table(lane.xray, lane.fusion, 60.0);
    std::mt19937 rng(7);
    std::vector<float> h, want(P), got(P);
    std::vector<uint8_t> v, want_v(P), got_v(P);
    int invalid = 0, fallback = 0;
    for (int line = 0; line < 40; ++line) {
      const double peak = line % 10 == 9 ? 75.0 : 5.0 + line;  // every tenth above the table
      make_profile(rng, n, peak, line % 2 == 0, h, v);
      const int slot = 0;
      project_fan_beam(h.data(), v.data(), 1, n, &slot, &lane.fusion, &lane.xray, P, want.data(),
                       want_v.data());
      project_line(table, h.data(), v.data(), got.data(), got_v.data());
      fallback += peak > 60;
      for (int i = 0; i < P; ++i) {
        ASSERT_EQ(got_v[i], want_v[i]) << "line " << line << " pixel " << i;
        invalid += !want_v[i];
        if (want_v[i]) ASSERT_EQ(got[i], want[i]) << "line " << line << " pixel " << i;
      }
    }
    EXPECT_GT(invalid, 0);  // the invalid samples were crossed
    EXPECT_EQ(fallback, 4);
  }
}

TEST(RayTable, RefusesAGridWithoutPitch) {
  LaneConfig lane = default_lane_config(0);
  lane.fusion.grid_pitch_mm = 0;
  EXPECT_THROW(build_ray_table(lane.xray, lane.fusion), std::exception);
  EXPECT_THROW(build_ray_table(default_lane_config(0).xray, default_lane_config(0).fusion, 0),
               std::exception);
}
