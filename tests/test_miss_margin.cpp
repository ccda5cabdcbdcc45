// What finding a miss would cost (offline/miss_margin.h): a faint bone is found at the
// largest fraction of the thresholds that finds it and at no larger one; a strong bone at
// the thresholds themselves; no bone at none; with learned thresholds, each statistic is
// lowered alone and the cheaper is reported, at the rate the extreme-value tails imply there
// (a closed form here); and a miss is measured in the fillet that holds it.
#include <gtest/gtest.h>

#include <cmath>

#include "core/lane_config.h"
#include "offline/miss_margin.h"
#include "pipeline/inspection.h"
#include "sim/synthetic_fillet.h"

using namespace rangex;

namespace {

using Bone = sim::PlantedBone;

InspectionParams params() {
  return default_lane_config(0).inspection;
}

bool finds(const FilletImage& img, const InspectionParams& p, const Bone& b, double tol) {
  for (const Blob& d : inspect_fillet(img, p, false).fragments)
    if (std::hypot(d.x_mm - b.x_mm, d.y_mm - b.y_mm) <= tol) return true;
  return false;
}

// Learned thresholds of one band for the round and needle statistics, Gumbel models of
// known location and scale, as product learning writes them.
InspectionParams learned(double round_t, double needle_t) {
  InspectionParams p = params();
  LearnedDetection& L = p.learned;
  L.band_edges_mm = {0, 1000};
  const double thr[kStatistics] = {round_t, needle_t, 6.0};
  for (int s = 0; s < kStatistics; ++s) {
    LearnedStatistic& ls = L.stats[size_t(s)];
    ls.thresholds = {thr[s]};
    ls.band_fraction = {1}, ls.band_pixels = {40000}, ls.band_thickness_mm = {15};
    ls.model.m0 = 3.0, ls.model.s0 = std::log(0.3);
    ls.model.log_n_ref = std::log(40000.0), ls.model.t_ref = 15;
  }
  return p;
}

}  // namespace

const Bone kFaint{5, 160, 1.2, 0.008}, kStrong{5, 160, 1.5, 0.06};
constexpr double kTol = 2;

TEST(MissMargin, AFaintBoneIsFoundAtTheLargestFractionThatFindsIt) {
  const FilletImage img = sim::synthetic_fillet(std::log(3600.0), -0.03, {kFaint}, 7);
  const InspectionParams p = params();
  ASSERT_FALSE(finds(img, p, kFaint, kTol));  // a miss at the thresholds
  const MarginOptions o;
  const MissMargin m = miss_margin(img, p, kFaint.x_mm, kFaint.y_mm, kTol, o);
  EXPECT_GT(m.found_at, o.floor);
  EXPECT_LT(m.found_at, 1);
  EXPECT_TRUE(finds(img, scaled_thresholds(p, m.found_at), kFaint, kTol));
  EXPECT_FALSE(finds(img, scaled_thresholds(p, m.found_at + o.step), kFaint, kTol));
  EXPECT_DOUBLE_EQ(scaled_thresholds(p, m.found_at).z_threshold, m.found_at * p.z_threshold);
  EXPECT_EQ(m.implied_frr, -1);        // fixed thresholds: no model to say what it costs
  EXPECT_EQ(m.stat, kEveryRejecting);  // the z threshold round and needle share
  std::printf("a faint bone (%.3f at its centre) found at %.2f of the thresholds\n",
              kFaint.attenuation, m.found_at);
}

TEST(MissMargin, AStrongBoneAtTheThresholdsNoBoneAtNone) {
  const FilletImage strong = sim::synthetic_fillet(std::log(3600.0), -0.03, {kStrong}, 7);
  EXPECT_EQ(miss_margin(strong, params(), kStrong.x_mm, kStrong.y_mm, kTol).found_at, 1);
  const FilletImage clean = sim::synthetic_fillet(std::log(3600.0), -0.03, {}, 7);
  MarginOptions o;
  o.floor = 0.6;
  EXPECT_EQ(miss_margin(clean, params(), kFaint.x_mm, kFaint.y_mm, kTol, o).found_at, 0);
}

TEST(MissMargin, LearnedThresholdsSayWhatLoweringOneStatisticWouldReject) {
  const FilletImage img = sim::synthetic_fillet(std::log(3600.0), -0.03, {kFaint}, 7);
  const double T[2] = {5.0, 5.5};  // round, needle
  const InspectionParams p = learned(T[0], T[1]);
  ASSERT_FALSE(finds(img, p, kFaint, kTol));
  const MarginOptions o;
  const MissMargin m = miss_margin(img, p, kFaint.x_mm, kFaint.y_mm, kTol, o);
  // Each rejecting statistic's Gumbel tail (location 3, scale 0.3 at the reference pixels
  // and thickness) at its threshold, over the one band every fillet holds.
  auto tail = [](double t) { return 1 - std::exp(-std::exp(-(t - 3.0) / 0.3)); };
  // The reference: each statistic lowered alone, the largest fraction on the grid that
  // finds the bone, and what the two tails imply there.
  double at[2] = {0, 0}, cost[2] = {0, 0};
  for (int s : {0, 1}) {
    for (int k = 0; at[s] == 0 && 1 - k * o.step >= o.floor; ++k)
      if (finds(img, scaled_thresholds(p, 1 - k * o.step, s), kFaint, kTol)) at[s] = 1 - k * o.step;
    cost[s] = tail(at[s] * T[s]) + tail(T[1 - s]);
  }
  ASSERT_TRUE(at[0] > 0 || at[1] > 0);
  const int cheaper = at[1] == 0 || (at[0] > 0 && cost[0] < cost[1]) ? 0 : 1;
  EXPECT_EQ(m.stat, cheaper);
  EXPECT_NEAR(m.found_at, at[cheaper], 1e-12);
  EXPECT_NEAR(m.implied_frr, cost[cheaper], 1e-9 * cost[cheaper]);
  EXPECT_GT(m.implied_frr, tail(T[0]) + tail(T[1]));
  std::printf(
      "lowering the round thresholds: found at %.2f (%.3f %% false rejects); the "
      "needle's: %.2f (%.3f %%)\n",
      at[0], 100 * cost[0], at[1], 100 * cost[1]);
  // Only the statistic asked for is scaled; the air statistic reports, never rejects.
  const InspectionParams half = scaled_thresholds(p, 0.5, kStatNeedle);
  EXPECT_EQ(half.learned.stats[kStatRound].thresholds.at(0), 5.0);
  EXPECT_EQ(half.learned.stats[kStatNeedle].thresholds.at(0), 2.75);
  const InspectionParams all = scaled_thresholds(p, 0.5);
  EXPECT_EQ(all.learned.stats[kStatRound].thresholds.at(0), 2.5);
  EXPECT_EQ(all.learned.stats[kStatNeedle].thresholds.at(0), 2.75);
  EXPECT_EQ(all.learned.stats[kStatAir].thresholds.at(0), 6.0);
}

TEST(MissMargin, AMissIsMeasuredInTheFilletThatHoldsIt) {
  InspectedFillet f;
  f.image = sim::synthetic_fillet(std::log(3600.0), -0.03, {kFaint}, 7);
  f.result = inspect_fillet(f.image, params(), false);
  ASSERT_EQ(f.result.decision, Decision::kPass);
  DetectionEval e;
  MissedFragment in{0, 3, "compact", 2.4, 0.8}, elsewhere = in, other_lane = in;
  in.x_mm = kFaint.x_mm, in.b_mm = kFaint.y_mm, in.tol_mm = kTol;
  elsewhere.b_mm = 900;  // past the fillet's 100-220 mm of belt
  other_lane.lane = 1, other_lane.x_mm = in.x_mm, other_lane.b_mm = in.b_mm;
  e.missed = {in, elsewhere, other_lane};
  measure_miss_margins(e, 0, {f}, params());
  EXPECT_GT(e.missed[0].found_at, 0);
  EXPECT_LT(e.missed[0].found_at, 1);
  EXPECT_EQ(e.missed[0].frr_at, -1);
  EXPECT_EQ(e.missed[1].found_at, -1);  // in no fillet: not measured
  EXPECT_EQ(e.missed[2].found_at, -1);
  // The miss's line says it.
  char want[64];
  std::snprintf(want, sizeof want, "; found at %.2f of the thresholds\n", e.missed[0].found_at);
  EXPECT_NE(missed_lines(e).find(want), std::string::npos) << missed_lines(e);
  // Beyond the floor, and a rate past half (the models' sum over bands is a bound there).
  DetectionEval said;
  MissedFragment gone = in, dear = in;
  gone.found_at = 0, gone.margin_floor = 0.3;
  dear.found_at = 0.52, dear.frr_at = 1.0, dear.margin_stat = kStatRound;
  said.missed = {gone, dear};
  const std::string text = missed_lines(said);
  EXPECT_NE(text.find("; not found at any fraction of the thresholds down to 0.30\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("; found at 0.52 of the round thresholds, where the learned models imply "
                      "most clean fillets rejected\n"),
            std::string::npos)
      << text;
}
