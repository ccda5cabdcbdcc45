// The bright enclosure (pipeline/bright_enclosure.h) against its definition, and what it buys
// the whitened kernels on marbled meat: a bone inside a fat streak, which the clip alone cuts
// to the streak's value, keeps its depth below the streak, while lean meat beside or between
// streaks, not enclosed on every line, stays as the clip left it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "pipeline/bright_enclosure.h"
#include "pipeline/masked_smooth.h"
#include "pipeline/matched_kernels.h"

using namespace rangex;

namespace {

float at(const std::vector<float>& v, int cols, int r, int c) {
  return v[size_t(r) * size_t(cols) + size_t(c)];
}

}  // namespace

// A bright block with a dip at its centre, a long bright band beside lean meat, and a
// fillet's edge: only what is enclosed on all four lines within the reach is lifted.
TEST(BrightEnclosure, LiftsWhatTheBrightEnclosesOnEveryLineAndNothingElse) {
  const int rows = 40, cols = 60;
  // Lean meat: a small texture (within +-0.4), so that the clip below has a spread.
  std::vector<float> z(size_t(rows) * cols);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) z[size_t(r) * cols + c] = 0.2f * float((7 * r + 3 * c) % 5 - 2);
  auto set = [&](int r0, int r1, int c0, int c1, float v) {
    for (int r = r0; r < r1; ++r)
      for (int c = c0; c < c1; ++c) z[size_t(r) * cols + c] = v;
  };
  set(5, 20, 5, 20, 6.f);     // a block of fat, 15 x 15 px
  set(11, 14, 11, 14, 3.f);   // a 3 x 3 px fragment inside it
  set(25, 28, 0, cols, 6.f);  // a band of fat along the rows
  set(31, 34, 0, cols, 6.f);  // and another, lean meat between them (rows 28-30)
  std::vector<uint8_t> use(z.size(), 1);
  for (int r = 0; r < rows; ++r) use[size_t(r) * cols + cols - 1] = 0;  // the fillet's edge
  set(10, 15, 53, cols, 6.f);  // fat reaching the edge, a dip in it on the edge's side
  z[size_t(12) * cols + 58] = 2.f;
  const float top = 1.5f;
  std::vector<float> e;
  bright_enclosure_excess(z.data(), use.data(), rows, cols, top, 4, e);
  EXPECT_FLOAT_EQ(at(e, cols, 12, 12), 6.f - top);  // the fragment: lifted by the fat's excess
  EXPECT_FLOAT_EQ(at(e, cols, 8, 8), 6.f - top);    // fat inside the block: as much
  EXPECT_FLOAT_EQ(at(e, cols, 5, 12), 0.f);         // the block's rim: lean meat on one side
  EXPECT_FLOAT_EQ(at(e, cols, 12, 4), 0.f);         // lean meat beside the block
  EXPECT_FLOAT_EQ(at(e, cols, 29, 30), 0.f);        // lean meat between the bands
  EXPECT_FLOAT_EQ(at(e, cols, 12, 58), 0.f);        // the fillet's edge encloses nothing
  EXPECT_TRUE(std::isnan(at(e, cols, 12, cols - 1)));
  // The clip with it (3 robust spreads of the lean texture, above its +-0.4): the fragment
  // 3 below the clipped fat, the fat at the clip, lean meat as it was; with no reach, the
  // clip alone, fragment and fat alike.
  std::vector<float> zc;
  clip_bright(z.data(), use.data(), rows, cols, 3.0, 4, 0, zc);
  const float held = at(zc, cols, 8, 8);
  EXPECT_GT(held, 0.4f);
  EXPECT_LT(held, 3.f);
  EXPECT_NEAR(at(zc, cols, 12, 12), held - 3.f, 1e-5);
  EXPECT_EQ(at(zc, cols, 26, 30), held);
  for (int c = 0; c < cols - 1; ++c) EXPECT_EQ(at(zc, cols, 29, c), at(z, cols, 29, c));
  clip_bright(z.data(), use.data(), rows, cols, 3.0, 0, 0, zc);
  EXPECT_EQ(at(zc, cols, 12, 12), at(zc, cols, 8, 8));
  bright_enclosure_excess(z.data(), use.data(), rows, cols, top, 0, e);
  EXPECT_FLOAT_EQ(at(e, cols, 12, 12), 0.f);
}
