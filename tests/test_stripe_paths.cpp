// The CPU stripe extractor's fast paths (AVX-512 blocks of 64 columns, portable groups of
// 16, single columns, the 16-bit path for tall frames, streamed results of large batches,
// several threads) against the per-column reference that the GPU kernels follow. Built
// twice: against the native pipeline and with AVX-512 switched off (the portable path).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "pipeline/stripe_extract.h"
#include "stripe_frames.h"

using namespace rangex;

namespace {

using test::Frames;
using test::make_frames;

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
