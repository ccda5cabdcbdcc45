// A closed gap's error under a kernel (pipeline/closure_spread.h) against its definition.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "pipeline/closure_spread.h"
#include "pipeline/masked_smooth.h"
#include "pipeline/matched_kernels.h"

namespace rangex {
namespace {

TEST(ClosureSpread, ReachCoversTheKernelsAroundAClosedPixelOnly) {
  const int R = 20, C = 20;
  std::vector<uint8_t> use(size_t(R) * C, 1);
  std::vector<float> e(use.size(), 0.0f);
  e[size_t(10) * C + 10] = 0.5f;
  e[0] = 0.7f;
  use[0] = 0;  // off the usable pixels: not a closure of this fillet
  const ClosureReach cr = closure_reach(e, use.data(), R, C, 3);
  EXPECT_EQ(cr.near.size(), 49u);  // the 7 x 7 box
  for (size_t i : cr.near) {
    const int r = int(i) / C, c = int(i) % C;
    EXPECT_LE(std::abs(r - 10), 3);
    EXPECT_LE(std::abs(c - 10), 3);
  }
  EXPECT_EQ(cr.e[0], 0.0f);
  EXPECT_TRUE(closure_reach(std::vector<float>(use.size(), 0.0f), use.data(), R, C, 3).empty());
  EXPECT_TRUE(closure_reach({}, use.data(), R, C, 3).empty());
}

TEST(ClosureSpread, AStatisticIsDividedByItsSpreadWithTheClosuresShare) {
  const int R = 1, C = 5;
  std::vector<uint8_t> use(C, 1);
  const ClosureReach cr = closure_reach({0, 0, 1, 0, 0}, use.data(), R, C, 1);
  ASSERT_EQ(cr.near.size(), 3u);
  SpreadProfile s;
  s.centre_mm = {10}, s.median = {0}, s.scale = {0.5};
  std::vector<float> v(C, 4.0f), t(C, 10.0f);
  discount_closures(v, cr, t.data(), s, std::vector<double>(cr.near.size(), 1.5));  // c = 3
  EXPECT_FLOAT_EQ(v[0], 4.0f);
  for (int i : {1, 2, 3}) EXPECT_FLOAT_EQ(v[size_t(i)], float(4 / std::sqrt(10.0))) << i;
  EXPECT_FLOAT_EQ(v[4], 4.0f);
}

// A closure alone: the closure's error is uniform over its range, at most sqrt(3) of its
// spread, and one error along a band two rows wide. Smoothed and brought to the white-noise
// spread, it reaches 3.7 spreads (more on a wider band); divided by its share it stays under
// sqrt(3).
TEST(ClosureSpread, AClosureAloneStaysUnderSqrt3Spreads) {
  const int R = 30, C = 40;
  std::vector<uint8_t> use(size_t(R) * C, 1);
  std::vector<float> e(use.size(), 0.0f), z(use.size(), 0.0f);
  for (int r = 14; r < 16; ++r)
    for (int c = 0; c < C; ++c) {
      e[size_t(r) * C + c] = 0.95f;
      z[size_t(r) * C + c] = float(-std::sqrt(3.0) * 0.95);
    }
  const double sigma = 1.0, gain = gaussian_noise_gain(sigma);
  std::vector<float> zs;
  masked_gaussian(z.data(), use.data(), R, C, sigma, zs);
  SpreadProfile s;
  s.centre_mm = {10}, s.median = {0}, s.scale = {gain};
  std::vector<float> t(use.size(), 10.0f);
  for (float& x : zs) x = float(x / gain);
  float before = 0;
  for (float x : zs) before = std::min(before, x);
  EXPECT_LT(before, -3.5);
  const ClosureReach cr = closure_reach(e, use.data(), R, C, 4);
  std::vector<double> sums;
  for (size_t i : cr.near)
    sums.push_back(
        masked_smooth_at(cr.e.data(), use.data(), R, C, sigma, sigma, -1, int(i) / C, int(i) % C));
  discount_closures(zs, cr, t.data(), s, sums);
  for (float x : zs) EXPECT_GT(x, -std::sqrt(3.0));
}

// The kernels' sums, scattered from the closed pixels, against apply_kernel_at read at each
// pixel near them: closures on the box's edges, a row along a lost line, unusable pixels
// among them, an asymmetric kernel.
TEST(ClosureSpread, KernelSumsScatteredEqualTheKernelReadAtEachNearPixel) {
  const int R = 23, C = 31, radius = 3, w = 2 * radius + 1;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<uint8_t> use(size_t(R) * C, 1);
  std::vector<float> e(use.size(), 0.0f);
  for (size_t i = 0; i < use.size(); ++i) {
    use[i] = u(rng) > 0.1;
    if (u(rng) < 0.06) e[i] = float(u(rng));
  }
  for (int c = 0; c < C; ++c) e[size_t(11) * C + c] = 0.8f;  // a lost line
  e[0] = 0.5f, e[size_t(R) * C - 1] = 0.9f, use[0] = 1, use[size_t(R) * C - 1] = 1;
  std::vector<double> taps(size_t(w) * w);
  for (double& h : taps) h = u(rng);
  const ClosureReach cr = closure_reach(e, use.data(), R, C, radius);
  ASSERT_FALSE(cr.empty());
  std::vector<double> acc(use.size(), 0.0);
  const std::vector<double> sums = closure_kernel_sums(cr, R, C, taps, radius, acc);
  ASSERT_EQ(sums.size(), cr.near.size());
  for (size_t k = 0; k < cr.near.size(); ++k) {
    const size_t i = cr.near[k];
    EXPECT_NEAR(
        sums[k],
        apply_kernel_at(cr.e.data(), use.data(), R, C, taps, radius, int(i) / C, int(i) % C), 1e-12)
        << i;
  }
  for (double a : acc) ASSERT_EQ(a, 0.0);  // left zeroed for the next kernel
}

}  // namespace
}  // namespace rangex
