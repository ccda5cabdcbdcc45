// A learned report's sphere claims held against the plant's own fragments
// (offline/claim_coverage.h): the bone a fragment holds weighed as the test sphere that holds
// as much, the claim of its band looked up, and only compact fragments covered.
#include <gtest/gtest.h>

#include <cmath>

#include "offline/claim_coverage.h"

using namespace rangex;

namespace {
// A compact fragment holding the bone of a test sphere of `d` mm (excess 2 x meat 0.03 /mm):
// its calcification's share of bone at 0.12 /mm, over meat at 0.03 /mm.
JudgedFragment holding(double d, double meat_mm, bool found, double calcification = 0.6) {
  JudgedFragment f;
  f.shape = "compact", f.size_mm = 1.3 * d, f.calcification = calcification;
  f.meat_mu = 0.03, f.excess_mu = calcification * (0.12 - 0.03);
  f.volume_mm3 = M_PI / 6 * d * d * d * (2 * 0.03) / f.excess_mu;
  f.meat_mm = meat_mm, f.found = found;
  return f;
}
}  // namespace

TEST(ClaimCoverage, WeighsAFragmentAsTheTestSphereHoldingItsBone) {
  const JudgedFragment f = holding(1.7, 12, true);
  EXPECT_NEAR(equivalent_sphere_mm(f, {}), 1.7, 1e-9);
  // A piece twice as dense equals a smaller sphere: 2^(-1/3).
  EXPECT_NEAR(equivalent_sphere_mm(f, {4, 0}), 1.7 / std::cbrt(2.0), 1e-9);
  // A fixed excess per mm replaces the ratio.
  EXPECT_NEAR(equivalent_sphere_mm(f, {2, 0.06}), 1.7, 1e-9);
  JudgedFragment old = f;
  old.excess_mu = -1;  // a truth written before it carried the bone's attenuation
  EXPECT_EQ(equivalent_sphere_mm(old, {}), -1);
}

TEST(ClaimCoverage, CoversWhatTheClaimOfItsBandSpeaksFor) {
  // 1.5 mm claimed up to 20 mm of meat, 2.5 mm from 20 to 35, nothing beyond.
  const std::vector<SphereClaim> claims = {{0, 20, 1.5}, {20, 35, 2.5}};
  JudgedFragment needle = holding(3.0, 10, false);
  needle.shape = "needle";
  JudgedFragment unweighed = holding(2.0, 10, true);
  unweighed.volume_mm3 = -1;
  const std::vector<JudgedFragment> fr = {
      holding(1.6, 10, true),   // covered, found
      holding(1.4, 10, false),  // less bone than claimed: not covered
      holding(2.0, 25, false),  // under thicker meat, where 2.5 mm is claimed: not covered
      holding(2.6, 25, false),  // covered, missed
      holding(3.0, 40, false),  // no claim that deep
      needle,                   // the sphere claims do not speak for needles
      unweighed,
  };
  const ClaimCoverage c = claim_coverage(fr, claims, {});
  EXPECT_EQ(c.covered, 2);
  EXPECT_EQ(c.found, 1);
  EXPECT_EQ(c.weighed, 5);  // the compact ones with their bone known
  EXPECT_EQ(c.unknown, 1);
  ASSERT_EQ(c.missed.size(), 1u);
  EXPECT_NEAR(c.missed[0].sphere_mm, 2.6, 1e-9);
  EXPECT_EQ(c.missed[0].claim_mm, 2.5);
  EXPECT_EQ(c.missed[0].fragment.meat_mm, 25);
  // A band's edge belongs to the band above it.
  EXPECT_EQ(claim_coverage({holding(2.0, 20, true)}, claims, {}).covered, 0);
  EXPECT_EQ(claim_coverage({holding(2.5, 20, true)}, claims, {}).covered, 1);
}

TEST(ClaimCoverage, SaysWhichCoveredFragmentsAreAsDenseAsThePiece) {
  // Both hold a 2 mm sphere's bone under a 1.5 mm claim. The piece is 0.06 /mm over the meat:
  // calcification 0.9 (0.081 /mm) is denser, 0.2 (0.018 /mm) spreads the same bone over a
  // fragment 1.5 times as wide, which stands out less than the sphere.
  const std::vector<SphereClaim> claims = {{0, 20, 1.5}};
  const ClaimCoverage c =
      claim_coverage({holding(2.0, 10, true, 0.9), holding(2.0, 10, false, 0.2)}, claims, {});
  EXPECT_EQ(c.covered, 2);
  EXPECT_EQ(c.found, 1);
  EXPECT_EQ(c.dense_covered, 1);
  EXPECT_EQ(c.dense_found, 1);
  // 0.6 is just short of the piece (0.054 /mm): covered, not dense.
  EXPECT_EQ(claim_coverage({holding(2.0, 10, true)}, claims, {}).dense_covered, 0);
}
