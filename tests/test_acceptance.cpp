// Issue 23's targets held against pooled counts (offline/acceptance.h): Wilson's interval
// against its definition solved independently (the p with |k/n - p| <= z sqrt(p(1 - p) / n),
// its edges found by bisection in Python), and each verdict at and beside its edge.
#include <gtest/gtest.h>

#include "offline/acceptance.h"

using namespace rangex;

TEST(Acceptance, WilsonsIntervalMatchesAnIndependentComputation) {
  const Interval a = wilson95(0, 306);
  EXPECT_NEAR(a.lo, 0.0, 1e-12);
  EXPECT_NEAR(a.hi, 0.012398, 2e-6);
  const Interval b = wilson95(4, 250);
  EXPECT_NEAR(b.lo, 0.006239, 2e-6);
  EXPECT_NEAR(b.hi, 0.040410, 2e-6);
  const Interval c = wilson95(87, 87);
  EXPECT_NEAR(c.lo, 0.957712, 2e-6);
  EXPECT_NEAR(c.hi, 1.0, 1e-12);
  const Interval none = wilson95(0, 0);
  EXPECT_EQ(none.lo, 0);
  EXPECT_EQ(none.hi, 1);
}

TEST(Acceptance, FalseRejectsNeedTheRateAndABoundThatShowsIt) {
  AcceptanceCounts c;
  c.fillets = 300, c.found = c.present = 10;
  c.clean = 147;  // 0 of 147: bound 2.5 %, not enough fillets to show 1.5 %
  Acceptance a = judge_acceptance(c);
  EXPECT_FALSE(a.false_rejects_met);
  EXPECT_NE(acceptance_text(c, a).find("not shown (too few fillets for the bound)"),
            std::string::npos);
  c.clean = 250;  // bound 1.52 %: still not
  EXPECT_FALSE(judge_acceptance(c).false_rejects_met);
  c.clean = 253;  // bound 1.50 %
  EXPECT_TRUE(judge_acceptance(c).false_rejects_met);
  c.clean = 1000, c.clean_rejected = 5;  // 0.5 %, bound 1.17 %
  EXPECT_TRUE(judge_acceptance(c).false_rejects_met);
  c.clean_rejected = 6;  // 0.6 %: the rate misses
  a = judge_acceptance(c);
  EXPECT_FALSE(a.false_rejects_met);
  EXPECT_NE(acceptance_text(c, a).find("= 0.60 % [0.28-1.30 %]: not met"), std::string::npos);
  c.clean = 0, c.clean_rejected = 0;  // no clean fillet: nothing shown
  a = judge_acceptance(c);
  EXPECT_FALSE(a.false_rejects_met);
  EXPECT_NE(acceptance_text(c, a).find("not shown (no clean fillet)"), std::string::npos);
}

TEST(Acceptance, DetectionsOfNoBoneAndRecallAtTheirEdges) {
  AcceptanceCounts c;
  c.clean = 400, c.fillets = 350, c.no_bone = 7;  // 0.020 a fillet
  c.found = 99, c.present = 100;
  Acceptance a = judge_acceptance(c);
  EXPECT_TRUE(a.no_bone_met);
  EXPECT_TRUE(a.recall_judged);
  EXPECT_TRUE(a.recall_met);
  EXPECT_TRUE(a.met());
  c.no_bone = 8;  // 0.023
  EXPECT_FALSE(judge_acceptance(c).no_bone_met);
  EXPECT_FALSE(judge_acceptance(c).met());
  c.no_bone = 0, c.found = 98;  // 98 %
  a = judge_acceptance(c);
  EXPECT_FALSE(a.recall_met);
  EXPECT_FALSE(a.met());
  EXPECT_NE(acceptance_text(c, a).find("98/100 = 98.0 % [93.0-99.4 %]: not met (>= 99 %)"),
            std::string::npos);
  c.found = c.present = 0;  // no fragment: the recall is not shown, so not met
  a = judge_acceptance(c);
  EXPECT_FALSE(a.met());
  EXPECT_NE(acceptance_text(c, a).find("not shown (no such fragment)"), std::string::npos);
}

TEST(Acceptance, RecallIsReportedNotJudgedWhereThePlantHoldsWhatOneEnergyCannotPromise) {
  AcceptanceCounts c;
  c.clean = 400, c.fillets = 350, c.found = 47, c.present = 57;
  c.needles = 27, c.cartilage = 3;
  const Acceptance a = judge_acceptance(c);
  EXPECT_FALSE(a.recall_judged);
  EXPECT_FALSE(a.recall_met);
  EXPECT_EQ(a.recall_exempt, "needles, cartilage");
  EXPECT_TRUE(a.met());  // the figures judged are met; the recall is reported
  EXPECT_NE(acceptance_text(c, a).find("reported, not judged: the plant holds needles, cartilage"),
            std::string::npos);
  c.needles = c.cartilage = 0, c.ribs = 14;
  EXPECT_EQ(judge_acceptance(c).recall_exempt, "rib plates");
}
