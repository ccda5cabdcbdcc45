// What a fragment's bone can show (offline/fragment_chance.h): its response is what the bone
// adds, whatever bone or noise already lies there, and grows with the bone; Phi(E - T)
// lies between how often such a piece is found and how often its statistic crosses the
// threshold near it, over many places; off the fillet or without a
// weight the truth can give, nothing is measured; and a plant's misses carry it.
#include <gtest/gtest.h>

#include <cmath>

#include "core/lane_config.h"
#include "offline/fragment_chance.h"
#include "pipeline/inspection.h"
#include "pipeline/test_pieces.h"
#include "sim/synthetic_fillet.h"

using namespace rangex;

namespace {

InspectionParams params() {
  return default_lane_config(0).inspection;
}

FilletImage fillet(uint64_t seed, const std::vector<sim::PlantedBone>& bones = {}) {
  return sim::synthetic_fillet(std::log(3600.0), -0.03, bones, seed);
}

double sphere_volume(double d_mm) {
  return M_PI / 6 * d_mm * d_mm * d_mm;
}

constexpr double kExcess = 0.06;  // per mm over the meat (twice the synthetic meat's 0.03)
constexpr double kTol = 2;

// Whether inspection finds a detection within kTol of (x, y).
bool finds(const FilletImage& img, const InspectionParams& p, double x, double y) {
  for (const Blob& d : inspect_fillet(img, p, false).fragments)
    if (std::hypot(d.x_mm - x, d.y_mm - y) <= kTol) return true;
  return false;
}

}  // namespace

TEST(FragmentChance, TheResponseIsWhatTheBoneAddsNotWhatLiesThere) {
  const InspectionParams p = params();
  const FilletImage clean = fillet(7);
  const FilletImage bony = fillet(7, {{5, 160, 1.5, 0.06}});  // a bone already where it lies
  const double v = sphere_volume(1.4);
  const FragmentChance a = fragment_chance(clean, p, 5, 160, kTol, v, kExcess);
  const FragmentChance b = fragment_chance(bony, p, 5, 160, kTol, v, kExcess);
  ASSERT_GT(a.response, 0);
  // The bone there changes the fillet's spread a little, not what one more piece adds.
  EXPECT_NEAR(b.response, a.response, 0.1 * a.response);
  EXPECT_DOUBLE_EQ(a.threshold, p.z_threshold);  // fixed thresholds: the z threshold
  // Its own peak: the texture on clean meat, the planted bone where there is one.
  EXPECT_LT(a.observed, p.z_threshold);
  EXPECT_GT(b.observed, p.z_threshold);
  EXPECT_NEAR(a.chance, 0.5 * std::erfc(-(a.response - a.threshold) / std::sqrt(2.0)), 1e-12);
  // More bone, more response: twice the excess about twice (the counts are linear in it to
  // a few percent at this size), a larger sphere more.
  const FragmentChance dense = fragment_chance(clean, p, 5, 160, kTol, v, 2 * kExcess);
  EXPECT_NEAR(dense.response, 2 * a.response, 0.15 * a.response);
  EXPECT_GT(fragment_chance(clean, p, 5, 160, kTol, sphere_volume(2.0), kExcess).response,
            a.response);
  std::printf(
      "a 1.4 mm sphere: response %.2f (with a bone there %.2f, twice as dense %.2f); the "
      "peak there %.2f (with the bone %.2f)\n",
      a.response, b.response, dense.response, a.observed, b.observed);
}

TEST(FragmentChance, ItsChanceBoundsHowOftenSuchPiecesAreFound) {
  // Pieces of one size at 40 places in 8 fillets. The chance is the statistic's at the
  // bone's peak. A detection needs its area too (0.3 mm2, two pixels), so it finds them less
  // often than the chances add up to; the statistic crossing anywhere within the matching's
  // distance (a detection of any area) finds them more often. Each within three binomial
  // deviations of its side.
  const InspectionParams p = params();
  InspectionParams any_area = p;
  any_area.min_fragment_area_mm2 = 0;
  const double d_mm = 0.9;
  double expected = 0, variance = 0;
  int found = 0, crossed = 0, placed = 0;
  for (uint64_t seed = 11; seed < 19; ++seed) {
    const FilletImage base = fillet(seed);
    for (int k = 0; k < 5; ++k) {
      const double x = -20 + 10 * k, y = 130 + 8 * double(seed - 11);
      const FragmentChance c = fragment_chance(base, p, x, y, kTol, sphere_volume(d_mm), kExcess);
      ASSERT_GE(c.chance, 0) << x << " " << y;
      expected += c.chance, variance += c.chance * (1 - c.chance);
      FilletImage with = base;
      TestPiece piece;
      piece.size_mm = d_mm;
      piece.col = int(std::lround((x - base.x0_mm) / base.pitch_mm));
      piece.row = int(std::lround((y - base.y0_mm) / base.step_mm));
      piece.height_mm = 0.5 * base.thickness[size_t(piece.row) * base.cols + piece.col];
      TestPieceMaterial m;
      m.excess_per_mm = kExcess;
      inject_test_piece(with, piece, 0, m);
      found += finds(with, p, x, y);
      crossed += finds(with, any_area, x, y);
      ++placed;
    }
  }
  std::printf(
      "%d pieces of %.1f mm: found %d, crossed the threshold within %.0f mm %d; their chances "
      "add up to %.1f (sd %.1f)\n",
      placed, d_mm, found, kTol, crossed, expected, std::sqrt(variance));
  // The size is one the chances do not settle: neither all found nor none.
  ASSERT_GT(expected, 0.15 * placed);
  ASSERT_LT(expected, 0.95 * placed);
  const double slack = 3 * std::sqrt(variance);
  EXPECT_LE(found, expected + slack);
  EXPECT_GE(crossed, expected - slack);
  EXPECT_LT(found, crossed + 1);
}

TEST(FragmentChance, NothingIsMeasuredOffTheFilletOrWithoutItsBone) {
  const InspectionParams p = params();
  const FilletImage img = fillet(7);
  EXPECT_EQ(fragment_chance(img, p, 5, 900, kTol, sphere_volume(2), kExcess).chance, -1);
  EXPECT_EQ(fragment_chance(img, p, -39.5, 101, kTol, sphere_volume(2), kExcess).chance, -1);
  EXPECT_EQ(fragment_chance(img, p, 5, 160, kTol, -1, kExcess).chance, -1);
  EXPECT_EQ(fragment_chance(img, p, 5, 160, kTol, sphere_volume(2), -1).chance, -1);
}

TEST(FragmentChance, APlantsFragmentsAndMissesCarryIt) {
  InspectedFillet f;
  f.image = fillet(7);
  f.result = inspect_fillet(f.image, params(), false);
  ASSERT_EQ(f.result.decision, Decision::kPass);
  DetectionEval e;
  JudgedFragment j;
  j.lane = 0, j.fillet = 3, j.shape = "compact", j.size_mm = 2.4, j.calcification = 0.8;
  j.volume_mm3 = sphere_volume(1.2), j.excess_mu = kExcess, j.meat_mu = 0.03;
  j.x_mm = 5, j.b_mm = 160, j.tol_mm = kTol;
  JudgedFragment small = j, weak = j, elsewhere = j;
  small.size_mm = 1.5;       // under 2 mm: not what recall counts
  weak.calcification = 0.4;  // weakly calcified: neither
  elsewhere.b_mm = 900;      // in no fillet
  e.judged = {j, small, weak, elsewhere};
  MissedFragment m{0, 3, "compact", 2.4, 0.8};
  m.x_mm = j.x_mm, m.b_mm = j.b_mm, m.tol_mm = kTol;
  e.missed = {m};
  measure_fragment_chances(e, 0, {f}, params());
  EXPECT_GE(e.judged[0].chance.chance, 0);
  EXPECT_EQ(e.judged[1].chance.chance, -1);
  EXPECT_EQ(e.judged[2].chance.chance, -1);
  EXPECT_EQ(e.judged[3].chance.chance, -1);
  EXPECT_EQ(e.missed[0].chance.chance, e.judged[0].chance.chance);
  EXPECT_EQ(e.missed[0].chance.response, e.judged[0].chance.response);
  int n = 0;
  EXPECT_DOUBLE_EQ(expected_recall(e, n), e.judged[0].chance.chance);
  EXPECT_EQ(n, 1);
  // The miss's line says it.
  char want[160];
  std::snprintf(want, sizeof want,
                "; one more sphere of its bone there adds %.1f to the %s statistic (its own "
                "peak there: %.1f) against a threshold of %.1f",
                e.missed[0].chance.response, statistic_name(e.missed[0].chance.stat),
                e.missed[0].chance.observed, e.missed[0].chance.threshold);
  EXPECT_NE(missed_lines(e).find(want), std::string::npos) << missed_lines(e);
}
