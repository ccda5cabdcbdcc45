// A steep wall's hidden rim closed as a vertical wall in the gap's middle, and the step it
// leaves uncertain.
#include <gtest/gtest.h>

#include <cmath>

#include "pipeline/wall_gaps.h"

namespace rangex {
namespace {

FilletImage row_image(std::vector<float> t) {
  FilletImage f;
  f.rows = 1, f.cols = int(t.size());
  f.thickness = std::move(t);
  f.mask.assign(f.size(), 0);
  f.xray.assign(f.size(), 1000);
  return f;
}

TEST(WallGaps, AShortGapBecomesAWallInItsMiddle) {
  FilletImage f = row_image({20, 20, NAN, NAN, NAN, 0, 0});
  EXPECT_EQ(close_wall_gaps(f, 4, 1.5), 3);
  EXPECT_EQ(f.thickness[2], 20);
  EXPECT_EQ(f.thickness[3], 0);  // the odd middle takes the foot
  EXPECT_EQ(f.thickness[4], 0);
  EXPECT_EQ(f.mask[2], 1);
  EXPECT_EQ(f.mask[4], 0);
}

TEST(WallGaps, LongGapsAndOpenEndsStayUnmeasured) {
  FilletImage f = row_image({20, NAN, NAN, NAN, NAN, NAN, 0, NAN, NAN});
  EXPECT_EQ(close_wall_gaps(f, 4, 1.5), 0);
  for (int k : {1, 2, 3, 4, 5, 7, 8}) EXPECT_TRUE(std::isnan(f.thickness[k])) << k;
  FilletImage g = row_image({NAN, 5, 5});
  EXPECT_EQ(close_wall_gaps(g, 4, 1.5), 0);
  EXPECT_TRUE(std::isnan(g.thickness[0]));
}

TEST(WallGaps, ColumnsAfterRows) {
  // A gap running across the rows (a leading wall) is closed along the columns.
  FilletImage f;
  f.rows = 4, f.cols = 2;
  f.thickness = {12, 12, NAN, NAN, NAN, NAN, 0, 0};
  f.mask.assign(f.size(), 0);
  EXPECT_EQ(close_wall_gaps(f, 4, 1.5), 4);
  EXPECT_EQ(f.thickness[2], 12);
  EXPECT_EQ(f.thickness[4], 0);
}

TEST(WallGaps, EveryClosureKeepsTheStepAcrossItsGap) {
  // Row 1's frame was lost: closed from rows 0 and 2, which differ by 6, 2 and 0 mm; row 3's
  // gap is a wall's rim, closed along its row between 16 and 0 mm.
  FilletImage f;
  f.rows = 4, f.cols = 3;
  f.thickness = {10, 10, 0, NAN, NAN, NAN, 16, 12, 0, 16, NAN, 0};
  f.mask.assign(f.size(), 0);
  EXPECT_EQ(close_wall_gaps(f, 4, 1.5), 4);
  EXPECT_EQ(f.thickness[3], 10);  // the odd middle takes the lower, as a wall's foot
  EXPECT_EQ(f.thickness[4], 10);
  EXPECT_EQ(f.thickness[10], 0);
  ASSERT_EQ(f.closure_step_mm.size(), f.size());
  EXPECT_EQ(f.closure_step_mm, (std::vector<float>{0, 0, 0, 6, 2, 0, 0, 0, 0, 0, 16, 0}));
  // var(ln P) = (slope step)^2 / 3, on the closed pixel and the rows either side.
  // mu = -d ln P / dT of a straight beam (b1 -0.03), and of a bent one (b2 0.0005).
  const auto straight = [](double) { return 0.03; };
  const auto bent = [](double t) { return -(-0.03 + 2 * 0.0005 * t); };
  const std::vector<float> v = closure_variance(f, straight);
  ASSERT_EQ(v.size(), f.size());
  const float six = float(0.18 * 0.18 / 3), two = float(0.06 * 0.06 / 3),
              sixteen = float(0.48 * 0.48 / 3);
  for (int r : {0, 1, 2}) EXPECT_FLOAT_EQ(v[size_t(r) * 3], six) << r;
  for (int r : {0, 1}) EXPECT_FLOAT_EQ(v[size_t(r) * 3 + 1], two) << r;
  for (int r : {2, 3}) EXPECT_FLOAT_EQ(v[size_t(r) * 3 + 1], sixteen) << r;  // the larger
  for (int r = 0; r < 4; ++r) EXPECT_EQ(v[size_t(r) * 3 + 2], 0) << r;
  EXPECT_EQ(v[9], 0);
  // A bent beam's slope is taken at the pixel's thickness: -0.03 + 2 * 0.0005 * 10.
  EXPECT_FLOAT_EQ(closure_variance(f, bent)[3], float(0.02 * 6 * 0.02 * 6 / 3));
  // A gap between ends of one height leaves nothing to carry.
  FilletImage g = row_image({20, 20, NAN, NAN, 20, 0, 0});
  EXPECT_EQ(close_wall_gaps(g, 4, 1.5), 2);
  EXPECT_TRUE(g.closure_step_mm.empty());
  EXPECT_TRUE(closure_variance(g, straight).empty());
}

// Rows of one fillet, stacked: each row's thickness repeated on `rows` rows, on the fillet
// where `on`; the middle row has the fillet above and below it.
FilletImage stacked(const std::vector<float>& t, const std::vector<uint8_t>& on, int rows) {
  FilletImage f;
  f.rows = rows, f.cols = int(t.size());
  for (int r = 0; r < rows; ++r) {
    f.thickness.insert(f.thickness.end(), t.begin(), t.end());
    f.mask.insert(f.mask.end(), on.begin(), on.end());
  }
  f.xray.assign(f.size(), 1000);
  return f;
}

TEST(WallGaps, TheOutlinesPixelCarriesItsWallAgainstTheDefinition) {
  // On the fillet from column 1 to 4: a cliff of 5 mm at its right (measured 2 there, its
  // inner neighbour 5) and a taper at its left (1.6 and 2). Mean square error of a thickness
  // uniform over [0, h] measured a: (a^3 + (h - a)^3) / (3 h), as step^2 / 3.
  const FilletImage f = stacked({0, 1.6f, 2, 5, 2, 0}, {0, 1, 1, 1, 1, 0}, 3);
  const std::vector<float> s = rim_steps(f);
  ASSERT_EQ(s.size(), f.size());
  auto step = [](double a, double h) {
    return float(std::sqrt((a * a * a + std::pow(h - a, 3)) / h));
  };
  const size_t mid = 6;                       // row 1
  EXPECT_FLOAT_EQ(s[mid + 4], step(2, 5));    // 2.569: the cliff
  EXPECT_FLOAT_EQ(s[mid + 1], step(1.6, 2));  // 1.442: the taper, most of it its own height
  for (int c : {0, 2, 3, 5}) EXPECT_EQ(s[mid + size_t(c)], 0) << c;  // inside, or off it
  // The first and last rows are the outline along the columns: nothing beyond them.
  EXPECT_FLOAT_EQ(s[2], 2);
  EXPECT_FLOAT_EQ(s[12 + 3], 5);
  // Measured at the wall's full height the error can be all of it: h.
  EXPECT_FLOAT_EQ(rim_steps(stacked({0, 5, 5, 0}, {0, 1, 1, 0}, 3))[4 + 1], 5);
  // closure_variance carries them with `rim`, nothing without (no gap was closed).
  const auto straight = [](double) { return 0.03; };
  EXPECT_TRUE(closure_variance(f, straight).empty());
  const std::vector<float> v = closure_variance(f, straight, true);
  ASSERT_EQ(v.size(), f.size());
  EXPECT_FLOAT_EQ(v[mid + 4], float(std::pow(0.03 * step(2, 5), 2) / 3));
  // ... and, like a closure's, on the rows either side: the middle row's interior takes the
  // first and last rows' outline.
  EXPECT_FLOAT_EQ(v[mid + 3], float(std::pow(0.03 * 5, 2) / 3));
}

}  // namespace
}  // namespace rangex
