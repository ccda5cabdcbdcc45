// A steep wall's hidden rim closed as a vertical wall in the gap's middle.
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

}  // namespace
}  // namespace rangex
