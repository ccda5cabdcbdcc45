// Lane assembly: registration by encoder with the laser-to-X-ray delay, cutting fillets,
// and the marks that make the inspection fail safe.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/lane_config.h"
#include "pipeline/lane_assembly.h"

using namespace rangex;

namespace {
constexpr int D = 480;

struct Feed {
  LaneConfig lane = default_lane_config(0);
  std::vector<FilletImage> out;
  LaneAssembler a{lane, [this](FilletImage&& f) { out.push_back(std::move(f)); }};
  // Thickness of a rectangular fillet occupying camera lines [l0, l1) and pixels [c0, c1).
  // blind: camera lines whose thickness is unknown everywhere (lost frames).
  void run(int lines, int l0, int l1, int c0, int c1, std::vector<int> missing = {},
           std::vector<int> blind = {}) {
    std::vector<float> t(D);
    std::vector<uint16_t> x(D);
    for (int n = 0; n < lines; ++n) {
      const int64_t e = 500 + n;
      if (std::find(missing.begin(), missing.end(), n) != missing.end()) {
        a.push_missing(e);
        continue;
      }
      const bool lost = std::find(blind.begin(), blind.end(), n) != blind.end();
      for (int i = 0; i < D; ++i)
        t[i] = lost ? NAN : (n >= l0 && n < l1 && i >= c0 && i < c1) ? 20.f : 0.f;
      // The X-ray line n sees what the camera saw at n - delay: encode that in the counts.
      const int s = n - lane.xray.delay_lines;
      for (int i = 0; i < D; ++i) x[i] = (s >= l0 && s < l1 && i >= c0 && i < c1) ? 1000 : 3600;
      a.push(e, t.data(), x.data());
    }
    a.flush();
  }
};
}  // namespace

TEST(LaneAssembly, RegistersThicknessToXrayByDelayAndCutsFillets) {
  Feed f;
  f.run(900, 100, 400, 100, 300);  // one fillet
  ASSERT_EQ(f.out.size(), 1u);
  const FilletImage& img = f.out[0];
  const int delay = f.lane.xray.delay_lines;
  EXPECT_EQ(img.first_line, 100 + delay - 2);  // two rows of margin
  EXPECT_EQ(img.rows, 300 + 4);
  EXPECT_EQ(img.missing_lines, 0);
  EXPECT_FALSE(img.touches_lane_edge);
  // Every fillet pixel's X-ray line saw the fillet: thickness and X-ray are registered.
  for (size_t i = 0; i < img.size(); ++i)
    if (img.mask[i]) EXPECT_EQ(img.xray[i], 1000) << i;
  EXPECT_DOUBLE_EQ(img.y0_mm, (img.first_line - delay) * f.lane.encoder_step_mm);
}

// A line the cameras lost inside a fillet neither cuts it in two nor fails it: its thickness
// is closed from the lines on either side, and it is not a missing line.
TEST(LaneAssembly, ABlindLineIsClosedFromItsNeighbours) {
  Feed f;
  f.run(900, 100, 400, 100, 300, {}, {250});
  ASSERT_EQ(f.out.size(), 1u);
  const FilletImage& img = f.out[0];
  EXPECT_EQ(img.missing_lines, 0);
  EXPECT_EQ(img.invalid_thickness_px, 0);
  EXPECT_GE(img.wall_gap_px, 200);
  const int row = 250 + f.lane.xray.delay_lines - int(img.first_line);
  for (int c = 0; c < img.cols; ++c) {
    const size_t i = size_t(row) * img.cols + c;
    EXPECT_FALSE(std::isnan(img.thickness[i])) << c;
    if (img.xray[i] == 1000) EXPECT_EQ(img.thickness[i], 20.f) << c;
  }
}

TEST(LaneAssembly, SeparateFilletsAndDebris) {
  Feed f;
  std::vector<float> t(D);
  std::vector<uint16_t> x(D, 3600);
  for (int n = 0; n < 1200; ++n) {
    for (int i = 0; i < D; ++i) {
      const bool a = n >= 100 && n < 300 && i >= 50 && i < 200;   // fillet
      const bool b = n >= 310 && n < 500 && i >= 220 && i < 400;  // fillet, 4 mm later
      const bool c = n >= 700 && n < 705 && i >= 10 && i < 14;    // a crumb
      t[i] = (a || b || c) ? 15.f : 0.f;
    }
    f.a.push(n, t.data(), x.data());
  }
  f.a.flush();
  EXPECT_EQ(f.out.size(), 2u);
  EXPECT_EQ(f.a.stats().debris, 1);
}

TEST(LaneAssembly, MissingLineInsideAFilletIsMarked) {
  Feed f;
  f.run(900, 100, 400, 100, 300, {300});
  ASSERT_EQ(f.out.size(), 1u);
  // Camera line 300 is gone: X-ray line 300 is missing, and X-ray line 300 + delay has no
  // thickness; both lie inside the fillet, which stays one region.
  EXPECT_EQ(f.out[0].missing_lines, 2);
  // Plus the first delay X-ray lines, which no camera line covers.
  EXPECT_EQ(f.a.stats().missing_lines, 2 + default_lane_config(0).xray.delay_lines);
}

TEST(LaneAssembly, FilletOnTheLaneEdgeIsMarked) {
  Feed f;
  f.run(900, 100, 400, 0, 150);
  ASSERT_EQ(f.out.size(), 1u);
  EXPECT_TRUE(f.out[0].touches_lane_edge);
}

namespace {
// Lines of a fillet on camera lines [l0, l1) over pixels [100, 300), pushed from `from` to
// `to` (exclusive) at counts n + shift.
void feed(Feed& f, int from, int to, int l0, int l1, int64_t shift) {
  std::vector<float> t(D);
  std::vector<uint16_t> x(D);
  for (int n = from; n < to; ++n) {
    for (int i = 0; i < D; ++i) t[i] = (n >= l0 && n < l1 && i >= 100 && i < 300) ? 20.f : 0.f;
    const int s = n - f.lane.xray.delay_lines;
    for (int i = 0; i < D; ++i) x[i] = (s >= l0 && s < l1 && i >= 100 && i < 300) ? 1000 : 3600;
    f.a.push(n + shift, t.data(), x.data());
  }
}
}  // namespace

TEST(LaneAssembly, AGapOfAnyLengthInsideAFilletIsBridgedInBoundedWork) {
  Feed f;
  f.lane.inspection.encoder_horizon_lines = 1 << 30;  // a gap, not a jump
  f.a.set_config(f.lane);
  // 2^29 counts missing in the middle of a fillet: walked count by count this would not end.
  feed(f, 0, 250, 100, 400, 0);
  feed(f, 250, 900, 100, 400, int64_t(1) << 29);
  f.a.flush();
  ASSERT_GE(f.out.size(), 1u);
  EXPECT_GT(f.out[0].missing_lines, 0);  // the fillet the gap touched fails safe
  for (const auto& img : f.out) EXPECT_GT(img.missing_lines, 0);
  EXPECT_EQ(f.a.stats().lines, 900 + (int64_t(1) << 29));
}

TEST(LaneAssembly, AJumpBeyondTheHorizonEndsTheOpenFilletNotInspected) {
  Feed f;
  feed(f, 0, 250, 100, 400, 0);
  feed(f, 250, 900, 100, 400, int64_t(1) << 40);
  f.a.flush();
  ASSERT_EQ(f.out.size(), 2u);
  EXPECT_NE(f.out[0].interrupted.find("encoder jumped"), std::string::npos) << f.out[0].interrupted;
  EXPECT_GT(f.out[1].missing_lines, 0);  // the rest, seen without its start
  EXPECT_EQ(f.a.stats().restarts, 1);
}

TEST(LaneAssembly, ARestartKeepsCompleteFilletsAndFailsTheOneUnderTheLaser) {
  Feed f;
  // A whole fillet (camera lines 100..199), then one only the laser has seen (lines
  // 500..530, whose X-ray lines would come 50 lines later).
  std::vector<float> t(D);
  std::vector<uint16_t> x(D, 3600);
  for (int n = 0; n < 531; ++n) {
    const bool a = n >= 100 && n < 200, b = n >= 500;
    for (int i = 0; i < D; ++i) t[i] = ((a || b) && i >= 100 && i < 300) ? 20.f : 0.f;
    const int s = n - f.lane.xray.delay_lines;
    for (int i = 0; i < D; ++i) x[i] = (s >= 100 && s < 200 && i >= 100 && i < 300) ? 1000 : 3600;
    f.a.push(n, t.data(), x.data());
  }
  EXPECT_EQ(f.out.size(), 1u);  // the whole one is out already
  EXPECT_FALSE(f.a.quiet());
  f.a.restart("encoder reset");
  ASSERT_EQ(f.out.size(), 2u);
  EXPECT_TRUE(f.out[0].interrupted.empty());
  EXPECT_EQ(f.out[0].missing_lines, 0);
  // Not lost with the restart: reported, and it cannot be inspected.
  EXPECT_EQ(f.out[1].interrupted, "encoder reset");
  EXPECT_GT(f.out[1].missing_lines, 0);
  EXPECT_TRUE(f.a.quiet());
  f.a.push(3, t.data(), x.data());  // afresh: any count
  EXPECT_EQ(f.a.stats().out_of_order, 0);
}

TEST(LaneAssembly, LinesEndingMidFilletLeaveItNotInspected) {
  Feed f;
  feed(f, 0, 300, 100, 400, 0);
  f.a.flush();
  ASSERT_EQ(f.out.size(), 1u);
  EXPECT_NE(f.out[0].interrupted.find("coming in"), std::string::npos) << f.out[0].interrupted;
}
