// Which lines of a lane are taken: in order; a resend within the window is a duplicate, a
// count behind that was never taken is backwards; far behind is an encoder reset.
#include <gtest/gtest.h>

#include "service/lane_admission.h"

using namespace rangex;
using Outcome = LaneAdmission::Outcome;

namespace {
void take(LaneAdmission& a, int64_t e) {
  const auto v = a.check(e);
  ASSERT_EQ(v.outcome, Outcome::kAccept) << e << ": " << v.message;
  a.commit(e, !v.restart.empty());
}
}  // namespace

TEST(LaneAdmission, ResendsAreDuplicatesAndSkippedCountsAreBackwards) {
  LaneAdmission a(3, 1024, true);
  EXPECT_FALSE(a.fed());
  for (int64_t e = 100; e < 200; ++e) take(a, e);
  take(a, 210);  // 200..209 never came
  EXPECT_EQ(a.last(), 210);
  EXPECT_EQ(a.check(150).outcome, Outcome::kDuplicate);
  EXPECT_EQ(a.check(210).outcome, Outcome::kDuplicate);
  const auto back = a.check(205);
  EXPECT_EQ(back.outcome, Outcome::kBackwards);
  EXPECT_NE(back.message.find("lane 3"), std::string::npos) << back.message;
  EXPECT_EQ(a.check(99).outcome, Outcome::kBackwards);  // before the first, inside the window
  EXPECT_EQ(a.check(211).outcome, Outcome::kAccept);
}

TEST(LaneAdmission, TheWindowForgetsOldCountsAsTheLaneMovesOn) {
  LaneAdmission a(0, 64, true);
  for (int64_t e = 0; e < 64; ++e) take(a, e);
  take(a, 100);  // slots of 64..99 are reused and must not look taken
  for (int64_t e = 64; e < 100; ++e) EXPECT_EQ(a.check(e).outcome, Outcome::kBackwards) << e;
  EXPECT_EQ(a.check(63).outcome, Outcome::kDuplicate);
  take(a, 1'000'000);  // a jump beyond the window clears it
  EXPECT_EQ(a.check(999'999).outcome, Outcome::kBackwards);
}

TEST(LaneAdmission, FarBehindIsAResetOrRefusedUntilCommanded) {
  LaneAdmission autoreset(0, 1024, true), manual(0, 1024, false);
  for (LaneAdmission* a : {&autoreset, &manual}) take(*a, int64_t(1) << 62);
  const auto v = autoreset.check(0);
  EXPECT_EQ(v.outcome, Outcome::kAccept);
  EXPECT_NE(v.restart.find("encoder reset"), std::string::npos) << v.restart;
  autoreset.commit(0, true);
  EXPECT_EQ(autoreset.last(), 0);
  EXPECT_EQ(autoreset.check(0).outcome, Outcome::kDuplicate);  // the window starts afresh

  const auto refused = manual.check(0);
  EXPECT_EQ(refused.outcome, Outcome::kBackwards);
  EXPECT_NE(refused.message.find("ResetLane"), std::string::npos) << refused.message;
  manual.request_reset("encoder reset by test");
  const auto commanded = manual.check(5);  // any count, even one taken before
  EXPECT_EQ(commanded.outcome, Outcome::kAccept);
  EXPECT_EQ(commanded.restart, "encoder reset by test");
  manual.commit(5, true);
  EXPECT_EQ(manual.check(6).restart, "");  // once
}
