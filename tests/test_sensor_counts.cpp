// A lane's device counts without devices: frame-id gaps, the joiner, and where a device that
// counts its own frames puts its first frame (sensors/frame_counts.h, sensors/line_joiner.h).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "sensors/frame_counts.h"
#include "sensors/line_joiner.h"

using namespace rangex;

namespace {

// Each frame says which device served it at which pulse, so a line shows what it joined.
LineBytes frame(int device, int64_t pulse) {
  return LineBytes(std::to_string(device) + ":" + std::to_string(pulse));
}

struct Joined {
  std::vector<int64_t> counts;
  int mismatched = 0;  // lines whose three frames are of different pulses
};

LineJoiner joiner(Joined& out) {
  return LineJoiner([&out](int64_t count, std::array<LineBytes, kLaneDevices>&& f) {
    out.counts.push_back(count);
    auto pulse = [&](int d) {
      const std::string s(f[size_t(d)].data(), f[size_t(d)].size());
      return s.substr(s.find(':') + 1);
    };
    for (int d = 1; d < kLaneDevices; ++d)
      if (pulse(d) != pulse(0)) ++out.mismatched;
  });
}

}  // namespace

TEST(FrameIdGaps, CountsTheFramesMissingOnTheSixteenBitRingThatSkipsZero) {
  FrameIdGaps g;
  EXPECT_EQ(g.next(65533), 0u);  // the first frame
  EXPECT_EQ(g.next(65534), 0u);
  EXPECT_EQ(g.next(2), 2u);  // 65535 and 1 lost; 0 is never sent
  EXPECT_EQ(g.next(1), 0u);  // late: not a gap of a ring's length
  EXPECT_EQ(g.next(3), 0u);
  EXPECT_EQ(g.next(3), 0u);  // repeated
  FrameIdGaps x;
  EXPECT_EQ(x.next(100000, true), 0u);
  EXPECT_EQ(x.next(100004, true), 3u);
  EXPECT_EQ(x.next(100001, true), 0u);
}

TEST(LineJoiner, JoinsByCountAndCountsWhatADeviceLackedOrSentTwice) {
  Joined out;
  LineJoiner j = joiner(out);
  for (int64_t n = 1; n <= 10; ++n)
    for (int d = 0; d < kLaneDevices; ++d) {
      if (d == 1 && n == 5) continue;  // cam1 loses frame 5
      j.add(d, n, frame(d, n));
    }
  j.add(2, 10, frame(2, 10));  // the X-ray sends 10 again
  EXPECT_EQ(out.counts, (std::vector<int64_t>{1, 2, 3, 4, 6, 7, 8, 9, 10}));
  EXPECT_EQ(out.mismatched, 0);
  const JoinerStats s = j.stats();
  EXPECT_EQ(s.lines, 9u);
  EXPECT_EQ(s.incomplete, 1u);
  EXPECT_EQ(s.lacked[1], 1u);
  EXPECT_EQ(s.lacked[0] + s.lacked[2], 0u);
  EXPECT_EQ(s.stale[2], 1u);
}

// Under load one device's receive thread can be far behind the others at the lane's start
// without having missed a pulse: its frames are late, not its count. Taking its first frame
// as the lane's next line (the rule before) put its lines a lag ahead of the others' for
// good, and the others' frames were then all too old to join.
TEST(SessionCountOffset, ADeviceThatStartedWithTheLaneKeepsItsCountHoweverLateItsFrames) {
  Joined out;
  LineJoiner j = joiner(out);
  const int64_t window = j.window();
  // Every session starts before the first pulse: the lane has no count yet.
  const std::optional<int64_t> at_start = j.newest();
  ASSERT_FALSE(at_start);
  for (int64_t n = 1; n <= 100; ++n) j.add(2, n, frame(2, n));  // the X-ray's thread ran ahead
  int64_t offset[2];
  for (int d = 0; d < 2; ++d) {
    offset[d] = session_count_offset(false, at_start, j.newest(), 1, window);
    EXPECT_EQ(offset[d], 0) << "camera " << d;
  }
  for (int64_t n = 1; n <= 400; ++n) {
    for (int d = 0; d < 2; ++d) j.add(d, n + offset[d], frame(d, n));
    if (n > 100) j.add(2, n, frame(2, n));
  }
  // The lane starts where every device had a frame (the X-ray's 100th); from there on every
  // pulse is one line of three frames of that pulse.
  EXPECT_EQ(out.mismatched, 0);
  ASSERT_FALSE(out.counts.empty());
  EXPECT_EQ(out.counts.front(), 100);
  EXPECT_EQ(out.counts.back(), 400);
  EXPECT_EQ(out.counts.size(), 301u);
  EXPECT_EQ(j.stats().stale[2], 0u);
  EXPECT_EQ(j.stats().incomplete, 0u);
}

TEST(SessionCountOffset, ADeviceThatJoinsARunningLaneOrRejoinsTakesTheNextLine) {
  const int64_t window = 64;
  // Joined a lane already beyond the window: its frame 1 is the lane's next line.
  EXPECT_EQ(session_count_offset(false, 500, 530, 1, window), 530);
  // Rejoined after its session was lost: likewise, wherever the lane stood at its start.
  EXPECT_EQ(session_count_offset(true, 3, 900, 1, window), 900);
  EXPECT_EQ(session_count_offset(true, std::nullopt, 900, 4, window), 897);
  // A pulse or two raced this session's start: the devices still count together.
  EXPECT_EQ(session_count_offset(false, 3, 200, 1, window), 0);
  // Nothing on the lane yet: nothing to align to.
  EXPECT_EQ(session_count_offset(true, std::nullopt, std::nullopt, 1, window), 0);
}
