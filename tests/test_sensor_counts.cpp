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

TEST(FrameIdDistance, IsTheNearerWayRoundTheRing) {
  EXPECT_EQ(frame_id_distance(65401, 65495), 94);
  EXPECT_EQ(frame_id_distance(65495, 65401), -94);
  EXPECT_EQ(frame_id_distance(65534, 2), 3);  // 65535, 1, 2: 0 is never sent
  EXPECT_EQ(frame_id_distance(2, 65534), -3);
  EXPECT_EQ(frame_id_distance(7, 7), 0);
  EXPECT_EQ(frame_id_distance(100000, 100004, true), 4);
  EXPECT_EQ(frame_id_distance(100004, 100000, true), -4);
}

// A receiver can drop the first frames of a session (Aravis's packet socket did, on a loaded
// machine: one device's first frame was id 65495 where the others' was 65401). Counted from
// 1, that device was 94 lines behind its lane for good: every frame of it too old to join,
// the lane blind. The devices share the trigger, so the ids say how many it lost.
TEST(LaneStartIds, ADeviceWhoseFirstFramesWereLostCountsFromWhereItsIdsSay) {
  Joined out;
  LineJoiner j = joiner(out);
  LaneStartIds ids;
  // cam0 and the X-ray deliver from id 65401 (pulse 1); cam1 lost pulses 1-94.
  EXPECT_FALSE(ids.first(0, 65401));
  EXPECT_FALSE(ids.first(2, 65401));
  EXPECT_FALSE(ids.first(1, 65495));
  EXPECT_EQ(ids.shift(0), 0);
  EXPECT_EQ(ids.shift(2), 0);
  EXPECT_EQ(ids.shift(1), 94);
  for (int64_t pulse = 1; pulse <= 400; ++pulse)
    for (int d = 0; d < kLaneDevices; ++d) {
      if (d == 1 && pulse <= 94) continue;              // never reached rangexd
      const int64_t own = d == 1 ? pulse - 94 : pulse;  // what the device counted
      j.add(d, own + ids.shift(d), frame(d, pulse));
    }
  EXPECT_EQ(out.mismatched, 0);
  ASSERT_FALSE(out.counts.empty());
  EXPECT_EQ(out.counts.front(), 95);
  EXPECT_EQ(out.counts.back(), 400);
  EXPECT_EQ(j.stats().stale[1], 0u);
}

TEST(LaneStartIds, TheEarliestIdIsTheLanesStartWhicheverDeviceDeliversFirst) {
  LaneStartIds ids;
  EXPECT_FALSE(ids.first(1, 65495));  // the one that lost frames delivers first
  EXPECT_EQ(ids.shift(1), 0);
  // The others' earlier ids move it on: the counts the lane holds of it are wrong now.
  EXPECT_TRUE(ids.first(0, 65401));
  EXPECT_EQ(ids.shift(1), 94);
  EXPECT_EQ(ids.shift(0), 0);
  EXPECT_FALSE(ids.first(2, 65402));  // lost one
  EXPECT_EQ(ids.shift(2), 1);
  EXPECT_EQ(ids.shift(1), 94);
  // Across the ring's end.
  LaneStartIds r;
  r.first(0, 65530);
  r.first(1, 3);
  EXPECT_EQ(r.shift(1), 8);
}

TEST(LaneStartIds, IdsThatDidNotStartTogetherKeepTheirCounts) {
  // Devices of other makers, whose ids began elsewhere: nothing says frames were lost.
  LaneStartIds ids;
  ids.first(0, 1);
  ids.first(1, 30000);
  ids.first(2, 1 + LaneStartIds::kMaxStartLoss + 1);
  for (int d = 0; d < kLaneDevices; ++d) EXPECT_EQ(ids.shift(d), 0) << d;
}
