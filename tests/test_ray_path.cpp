// Fan-beam path length through a height profile (Laser Range Imaging eq. 39-40) against brute
// force.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "core/ray_path.h"

using namespace rangex;

namespace {
// Numerical integration along the ray in tiny steps.
double brute_force(const std::vector<float>& h, double x0, double pitch, double xd, double zd,
                   double xs, double zs) {
  const double top = *std::max_element(h.begin(), h.end());
  const double slope = (xs - xd) / (zs - zd), sec = std::sqrt(1 + slope * slope);
  double len = 0;
  const double dz = 1e-4;
  for (double z = 0.5 * dz; z < top; z += dz) {
    const double x = xd + slope * (z - zd);
    const double f = (x - x0) / pitch;
    const int i = int(std::floor(f));
    double hh = 0;
    if (i >= 0 && i + 1 < int(h.size())) hh = h[i] + (h[i + 1] - h[i]) * (f - i);
    if (z < hh) len += dz;
  }
  return len * sec;
}
}  // namespace

TEST(RayPath, FlatSlabIsThicknessOverCosine) {
  std::vector<float> h(1001, 30.f);
  const ProfileGrid g{h.data(), nullptr, int(h.size()), -100, 0.2, 30.f};
  for (double xd : {0.0, 40.0, -90.0}) {
    const PathResult r = ray_path_length(g, xd, -15, 0, 700);
    const double theta = std::atan2(std::abs(xd), 715.0);
    EXPECT_NEAR(r.length_mm, 30.0 / std::cos(theta), 1e-6) << xd;
    EXPECT_TRUE(r.valid);
  }
}

TEST(RayPath, DomeMatchesBruteForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> ux(-95, 95);
  std::vector<float> h(1001);
  for (int i = 0; i < 1001; ++i) {
    const double x = -100 + 0.2 * i, r = (x - 10) / 45;
    h[i] = r * r < 1 ? float(40 * (1 - r * r) + 2 * std::sin(x)) : 0.f;
  }
  const float top = *std::max_element(h.begin(), h.end());
  const ProfileGrid g{h.data(), nullptr, 1001, -100, 0.2, top};
  for (int k = 0; k < 200; ++k) {
    const double xd = ux(rng);
    const double ref = brute_force(h, -100, 0.2, xd, -15, 0, 700);
    EXPECT_NEAR(ray_path_length(g, xd, -15, 0, 700).length_mm, ref, 2e-3) << "xd " << xd;
  }
}

TEST(RayPath, InvalidSampleOnThePathInvalidatesIt) {
  std::vector<float> h(101, 10.f);
  std::vector<uint8_t> v(101, 1);
  v[50] = 0;
  const ProfileGrid g{h.data(), v.data(), 101, -10, 0.2, 10.f};
  EXPECT_FALSE(ray_path_length(g, 0.0, -15, 0, 700).valid);  // straight up through sample 50
  EXPECT_TRUE(ray_path_length(g, -5.0, -15, 0, 700).valid);
}
