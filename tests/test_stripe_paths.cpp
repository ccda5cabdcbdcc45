// The CPU stripe extractor's fast paths (AVX-512 blocks of 64 columns, portable groups of
// 16, single columns, the 16-bit path for tall frames, streamed results of large batches,
// several threads) against the per-column reference that the GPU kernels follow. Built
// twice: against the native pipeline and with AVX-512 switched off (the portable path).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "pipeline/stripe_extract.h"

using namespace rangex;

namespace {

struct Frames {
  int count, width, height;
  std::vector<uint8_t> px;
  uint8_t& at(int f, int y, int c) { return px[(size_t(f) * height + y) * width + c]; }
};

// Stripes with a Gaussian core and a one-sided exponential tail over a noisy background,
// written independently of the simulator, plus the awkward columns every path must treat
// as the reference does.
Frames make_frames(int count, int width, int height, unsigned seed) {
  Frames fr{count, width, height, std::vector<uint8_t>(size_t(count) * width * height)};
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 3);
  std::uniform_real_distribution<double> u(0, 1);
  for (int f = 0; f < count; ++f)
    for (int c = 0; c < width; ++c) {
      const double centre = 3 + u(rng) * (height - 6), amp = 30 + u(rng) * 260;
      const double sigma = 0.7 + u(rng) * 1.3, tail = u(rng) * 0.5, decay = 1 + u(rng) * 3;
      for (int y = 0; y < height; ++y) {
        const double d = y - centre;
        double g = 10 + noise(rng) + amp * std::exp(-0.5 * d * d / (sigma * sigma));
        if (d > 0) g += amp * tail * std::exp(-d / decay);
        fr.at(f, y, c) = uint8_t(std::clamp(std::lround(g), 0L, 255L));
      }
    }
  for (int f = 0; f < count; ++f) {
    const int h = height;
    for (int y = h / 8; y < h / 8 + std::min(h / 2, 60); ++y)
      fr.at(f, y, 7 % width) = 230;                                         // glare
    for (int y = h / 2; y < h / 2 + 4; ++y) fr.at(f, y, 33 % width) = 255;  // saturated
    for (int y = 0; y < h; ++y) fr.at(f, y, 64 % width) = 9;                // no stripe
    for (int y = h / 3; y < h / 3 + 3; ++y) fr.at(f, y, 70 % width) = 150;  // flat top
    fr.at(f, 0, 100 % width) = 250;                                         // peak on row 0
    fr.at(f, h - 1, 101 % width) = 250;                                     // on the last row
  }
  return fr;
}

constexpr StripeMethod kMethods[] = {StripeMethod::kCentroid, StripeMethod::kSquared,
                                     StripeMethod::kBinary,   StripeMethod::kGaussian3,
                                     StripeMethod::kParabola, StripeMethod::kShifted,
                                     StripeMethod::kModified};

// Every field of every column equal to the reference: flags, peaks and widths exactly,
// rows and sums to float rounding (1e-4 px; the paths add the same terms in other orders).
void expect_equal_to_reference(const Frames& fr, StripeMethod m, int threads) {
  StripeSlot slot;
  slot.params.method = m;
  slot.scatter = {0.1, -0.2, 0.05};
  const std::vector<int> slots(fr.count, 0);
  StripeOutput fast, ref;
  extract_stripes(fr.px.data(), fr.count, fr.width, fr.height, slots.data(), &slot, fast, threads);
  extract_stripes_reference(fr.px.data(), fr.count, fr.width, fr.height, slots.data(), &slot, ref);
  ASSERT_EQ(fast.row.size(), ref.row.size());
  int valid = 0;
  for (size_t i = 0; i < ref.row.size(); ++i) {
    const auto where = [&] {
      return std::string(stripe_method_name(m)) + " frame " + std::to_string(i / fr.width) +
             " column " + std::to_string(i % fr.width);
    };
    ASSERT_EQ(fast.valid[i], ref.valid[i]) << where();
    ASSERT_EQ(fast.peak[i], ref.peak[i]) << where();
    ASSERT_EQ(fast.width[i], ref.width[i]) << where();
    if (!ref.valid[i]) {
      ASSERT_TRUE(std::isnan(fast.row[i])) << where();
      continue;
    }
    ++valid;
    ASSERT_NEAR(fast.row[i], ref.row[i], 1e-4) << where();
    ASSERT_NEAR(fast.centroid[i], ref.centroid[i], 1e-4) << where();
    ASSERT_NEAR(fast.asym[i], ref.asym[i], 1e-5) << where();
  }
  // The frames hold mostly real stripes: an extractor that found none would not pass.
  EXPECT_GT(valid, int(ref.row.size()) * 3 / 4) << stripe_method_name(m);
}

}  // namespace

TEST(StripePaths, FullWidthFramesEqualReference) {
  const Frames fr = make_frames(3, 640, 200, 1);
  for (StripeMethod m : kMethods) expect_equal_to_reference(fr, m, 1);
}

TEST(StripePaths, RaggedWidthEqualsReference) {
  // 600 = 9 blocks of 64 + a group of 16 + 8 single columns.
  const Frames fr = make_frames(3, 600, 120, 2);
  for (StripeMethod m : kMethods) expect_equal_to_reference(fr, m, 2);
}

TEST(StripePaths, TallFramesEqualReference) {
  // More than 256 rows: the row index no longer fits a byte.
  const Frames fr = make_frames(2, 160, 300, 3);
  for (StripeMethod m : kMethods) expect_equal_to_reference(fr, m, 1);
}

TEST(StripePaths, LargeBatchStreamedEqualsReference) {
  // 320 frames x 640 columns of results (4.3 MB) exceed the size above which they are
  // streamed past the cache.
  const Frames fr = make_frames(320, 640, 24, 4);
  expect_equal_to_reference(fr, StripeMethod::kModified, 1);
  expect_equal_to_reference(fr, StripeMethod::kSquared, 2);
}
