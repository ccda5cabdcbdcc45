// Test pieces injected by Beer-Lambert (pipeline/test_pieces.h) against their geometry: a
// sphere's central transmission and its integrated excess attenuation (its volume times the
// excess attenuation, magnified across the belt by the fan beam), a needle's likewise; and
// the sensitivity measurement finding large pieces and not finding pieces of no contrast.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <tuple>

#include "pipeline/binomial_tail.h"
#include "pipeline/inspection.h"
#include "pipeline/sensitivity.h"
#include "pipeline/test_pieces.h"

namespace rangex {
namespace {

FilletImage flat(int rows, int cols, double counts, double t) {
  FilletImage img;
  img.rows = rows, img.cols = cols;
  img.xray.assign(img.size(), uint16_t(counts));
  img.thickness.assign(img.size(), float(t));
  img.mask.assign(img.size(), 1);
  img.source_z_mm = 700, img.detector_z_mm = -15;
  return img;
}

double integrated_excess(const FilletImage& before, const FilletImage& after) {
  double s = 0;
  for (size_t i = 0; i < before.size(); ++i)
    s += -std::log(double(after.xray[i]) / before.xray[i]) * before.pitch_mm * before.step_mm;
  return s;
}

TEST(TestPieces, SphereAttenuatesByItsChordAndVolume) {
  const FilletImage base = flat(80, 80, 60000, 20);
  FilletImage img = base;
  TestPiece p;
  p.shape = TestPiece::kSphere, p.size_mm = 3, p.row = 40, p.col = 40, p.height_mm = 10;
  TestPieceMaterial m;
  m.excess_per_mm = 0.09;
  inject_test_piece(img, p, 0.03, m);
  const double mag = 715.0 / 690.0;
  // Integrated over the detector: volume x excess, magnified across the belt.
  EXPECT_NEAR(integrated_excess(base, img), 0.09 * M_PI * 27 / 6 * mag, 0.01);
  // The centre pixel: nearly the full 3 mm chord (averaged over its 0.4 mm).
  const double centre = -std::log(img.xray[size_t(40) * 80 + 40] / 60000.0);
  EXPECT_GT(centre, 0.09 * 2.9);
  EXPECT_LT(centre, 0.09 * 3.0 + 1e-3);
  // The ratio form: twice the meat's own attenuation.
  FilletImage rel = base;
  TestPieceMaterial r;
  r.excess_ratio = 2;
  inject_test_piece(rel, p, 0.045, r);
  EXPECT_NEAR(integrated_excess(base, rel), integrated_excess(base, img), 1e-3);
}

TEST(TestPieces, NeedleVolumeAndBlurKeepTheTotal) {
  const FilletImage base = flat(80, 80, 60000, 20);
  TestPiece p;
  p.shape = TestPiece::kNeedle, p.size_mm = 5, p.row = 40, p.col = 40, p.height_mm = 5;
  p.angle_rad = 0.6;
  TestPieceMaterial m;
  m.excess_per_mm = 0.09, m.needle_diameter_mm = 0.6;
  FilletImage sharp = base;
  inject_test_piece(sharp, p, 0.03, m);
  const double r = 0.3, len = 5 - 2 * r;
  const double volume = M_PI * r * r * len + 4.0 / 3 * M_PI * r * r * r;
  // Across the belt the fan beam magnifies; the needle lies at 0.6 rad, so its projection's
  // area grows by a factor between 1 and mag. Bounds, then blur's conservation.
  const double mag = 715.0 / 695.0;
  EXPECT_GT(integrated_excess(base, sharp), 0.09 * volume * 0.97);
  EXPECT_LT(integrated_excess(base, sharp), 0.09 * volume * mag * 1.03);
  FilletImage blurred = base;
  blurred.detector_sigma_px = 0.8;
  FilletImage b2 = blurred;
  inject_test_piece(b2, p, 0.03, m);
  // Blur spreads the transmission, not the attenuation: the total of -ln falls slightly.
  EXPECT_NEAR(integrated_excess(blurred, b2), integrated_excess(base, sharp),
              0.05 * integrated_excess(base, sharp));
  EXPECT_LT(-std::log(b2.xray[size_t(40) * 80 + 40] / 60000.0),
            -std::log(sharp.xray[size_t(40) * 80 + 40] / 60000.0));
}

// A fillet of noisy counts over a smooth dome: what the inspection sees of clean meat.
FilletImage noisy_dome(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> nd;
  FilletImage img = flat(220, 140, 0, 0);
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      const size_t i = size_t(r) * img.cols + c;
      const double u = (r - 110) / 100.0, v = (c - 70) / 62.0, q = 1 - u * u - v * v;
      img.mask[i] = q > 0;
      img.thickness[i] = q > 0 ? float(2 + 20 * q) : NAN;
      const double mean = 3600 * std::exp(-0.03 * (q > 0 ? img.thickness[i] : 0));
      img.xray[i] = uint16_t(std::lround(mean + std::sqrt(mean / 10) * nd(rng)));
    }
  return img;
}

// The domes of seeds first..last, as the sensitivity's fillets (the meat's attenuation 0.03).
struct Domes {
  std::vector<FilletImage> images;
  std::vector<SensitivityFillet> fillets;
  Domes(uint64_t first, uint64_t last) {
    for (uint64_t seed = first; seed <= last; ++seed) images.push_back(noisy_dome(seed));
    for (const FilletImage& i : images) fillets.push_back({&i, -0.03, 0});
  }
};

TEST(Sensitivity, FindsLargePiecesAndNotPiecesWithoutContrast) {
  // Enough pieces of one size in one band for a claim at 95 % with 95 % confidence: 48 of
  // 48 found bound the rate at 0.946, 60 of 60 at 0.957 (detection_curve.h).
  const Domes domes(1, 8);
  const std::vector<SensitivityFillet>& fs = domes.fillets;
  InspectionParams p;
  SensitivityOptions o;
  o.sizes_mm = {4};
  o.pieces_per_fillet = 8;
  o.band_edges_mm = {0, 100};
  const SensitivityResult big = measure_sensitivity(fs, p, o);
  int injected = 0, found = 0;
  for (const auto& c : big.cells) injected += c.injected, found += c.found;
  EXPECT_GE(injected, 2 * 60);
  EXPECT_EQ(found, injected);
  o.material.excess_ratio = 1e-4;  // as good as meat: nothing to find
  const SensitivityResult none = measure_sensitivity(fs, p, o);
  found = 0;
  for (const auto& c : none.cells) found += c.found;
  EXPECT_EQ(found, 0);
  EXPECT_TRUE(none.claims.empty());
  // What the report states, checked on the same pieces, holds; on pieces that cannot be
  // seen it fails with every piece counted.
  ASSERT_FALSE(big.stated.empty());
  for (const StatedCheck& k : check_stated_claims(big.stated, big, o.rate)) {
    EXPECT_TRUE(k.held);
    EXPECT_GT(k.injected, 0);
  }
  for (const StatedCheck& k : check_stated_claims(big.stated, none, o.rate)) {
    EXPECT_FALSE(k.held);
    EXPECT_EQ(k.found, 0);
    EXPECT_GT(k.injected, 0);
  }
}

// The same pieces measured under several thresholds at once (learning's trade-off) find what
// each set's own measurement finds, piece for piece.
TEST(Sensitivity, EachSetOfThresholdsFindsWhatItsOwnMeasurementFinds) {
  const Domes domes(11, 13);
  const std::vector<SensitivityFillet>& fs = domes.fillets;
  SensitivityOptions o;
  o.sizes_mm = {1, 1.5, 2};
  o.pieces_per_fillet = 6;
  std::vector<LearnedDetection> sets(3);
  const double level[3] = {3, 6, 12};
  for (size_t k = 0; k < sets.size(); ++k) {
    sets[k].band_edges_mm = {0, 10, 1000};
    for (auto& st : sets[k].stats) st.thresholds = {level[k], level[k]};
  }
  InspectionParams p;
  const std::vector<SensitivityResult> each = measure_sensitivity_each(fs, p, sets, o);
  ASSERT_EQ(each.size(), sets.size());
  std::vector<int> found;
  for (size_t k = 0; k < sets.size(); ++k) {
    p.learned = sets[k];
    const SensitivityResult own = measure_sensitivity(fs, p, o);
    ASSERT_EQ(each[k].cells.size(), own.cells.size());
    int n = 0;
    for (size_t c = 0; c < own.cells.size(); ++c) {
      const SensitivityCell &a = each[k].cells[c], &b = own.cells[c];
      EXPECT_EQ(std::tie(a.shape, a.size_mm, a.band, a.injected, a.found),
                std::tie(b.shape, b.size_mm, b.band, b.injected, b.found));
      n += b.found;
    }
    EXPECT_EQ(each[k].summary, own.summary);
    EXPECT_EQ(each[k].inspections, own.inspections);
    found.push_back(n);
  }
  std::printf("pieces found under thresholds 3, 6, 12: %d, %d, %d\n", found[0], found[1], found[2]);
  EXPECT_GT(found[0], found[2]);  // the sets find apart
}

// Spheres seen in bands 0-4 (edges 0, 5, ... 25 mm); `claimed[b]`: the size claimed there
// (0: none).
SensitivityResult claimed_by_band(const std::vector<double>& claimed) {
  SensitivityResult r;
  r.band_edges_mm = {0, 5, 10, 15, 20, 1000};
  for (int b = 0; b < int(claimed.size()); ++b) {
    r.cells.push_back({0, 2.0, b, 20, 20});
    if (claimed[size_t(b)] > 0)
      r.claims.push_back(
          {0, b, r.band_edges_mm[size_t(b)], r.band_edges_mm[size_t(b) + 1], claimed[size_t(b)]});
  }
  return r;
}

TEST(Sensitivity, TheReportStatesTheSmallestSizeFromTheThinnestBandOrFromWhereItBegins) {
  SensitivityOptions o;
  SensitivityResult r = claimed_by_band({1.5, 1.5, 2.0, 3.0, 0});
  state_claims(r, o);
  ASSERT_EQ(r.stated.size(), 1u);
  EXPECT_EQ(r.stated[0].size_mm, 1.5);
  EXPECT_EQ(r.stated[0].first_band, 0);
  EXPECT_EQ(r.stated[0].last_band, 1);
  EXPECT_EQ(r.summary.at(0), "1.5 mm calcified sphere at 95 % up to 10 mm of meat");
  // The thinnest band claims nothing (a steep wall's rim): stated from where claims begin,
  // not "no claim".
  r = claimed_by_band({0, 2.0, 2.0, 2.5, 2.5});
  state_claims(r, o);
  ASSERT_EQ(r.stated.size(), 1u);
  EXPECT_EQ(r.stated[0].size_mm, 2.0);
  EXPECT_EQ(r.stated[0].first_band, 1);
  EXPECT_EQ(r.stated[0].last_band, 2);
  EXPECT_EQ(r.summary.at(0), "2.0 mm calcified sphere at 95 % from 5 mm of meat up to 15 mm");
  EXPECT_EQ(r.stated[0].text, r.summary.at(0));
  r = claimed_by_band({0, 0, 0, 0, 0});
  state_claims(r, o);
  EXPECT_TRUE(r.stated.empty());
  EXPECT_EQ(r.summary.at(0).rfind("no claim", 0), 0u);
}

TEST(Sensitivity, StatedClaimPoolsItsBandsAndSizeOnly) {
  SensitivityResult m;
  // sphere 2 mm: bands 0-2; sphere 3 mm and a needle of 2 mm beside them.
  m.cells = {{0, 2.0, 0, 20, 20},
             {0, 2.0, 1, 20, 18},
             {0, 2.0, 2, 20, 0},
             {0, 3.0, 1, 50, 0},
             {1, 2.0, 1, 50, 0}};
  const StatedClaim up_to_b1{0, 2.0, 0, 1, 10};
  const StatedClaim up_to_b2{0, 2.0, 0, 2, 15};
  const std::vector<StatedCheck> k = check_stated_claims({up_to_b1, up_to_b2}, m, 0.95);
  ASSERT_EQ(k.size(), 2u);
  EXPECT_EQ(k[0].injected, 40);
  EXPECT_EQ(k[0].found, 38);  // 95 %: held
  EXPECT_TRUE(k[0].held);
  EXPECT_EQ(k[1].injected, 60);
  EXPECT_EQ(k[1].found, 38);
  EXPECT_FALSE(k[1].held);
  // Nothing of its kind measured: not held (nothing shows it).
  EXPECT_FALSE(check_stated_claims({{1, 5.0, 0, 3, 20}}, m, 0.95).at(0).held);
  // 38 of 60 at a claimed 95 % is evidence against the claim, not chance.
  EXPECT_TRUE(k[1].contradicted);
  EXPECT_LT(k[1].p_at_rate, 1e-9);
  EXPECT_FALSE(k[0].contradicted);
}

// The binomial lower tail against the sum of its terms computed another way (products of
// the rate, in long double) and a value by hand: 14 of 15 at 95 % or fewer is 1 - 0.95^15.
TEST(BinomialTail, MatchesItsTermsAndTheEdges) {
  EXPECT_NEAR(binomial_at_most(14, 15, 0.95), 1 - std::pow(0.95, 15), 1e-12);
  EXPECT_NEAR(binomial_at_most(0, 10, 0.3), std::pow(0.7, 10), 1e-12);
  for (int n : {1, 7, 40})
    for (double p : {0.05, 0.5, 0.95})
      for (int k = 0; k < n; ++k) {
        long double sum = 0, choose = 1;  // C(n, i), built up term by term
        for (int i = 0; i <= k; ++i) {
          if (i > 0) choose = choose * (n - i + 1) / i;
          sum += choose * std::pow((long double)p, i) * std::pow(1 - (long double)p, n - i);
        }
        EXPECT_NEAR(binomial_at_most(k, n, p), double(sum), 1e-10) << n << " " << p << " " << k;
      }
  EXPECT_EQ(binomial_at_most(5, 5, 0.9), 1.0);
  EXPECT_EQ(binomial_at_most(-1, 5, 0.9), 0.0);
  // Hundreds of pieces at a rate near 1 (exact values by rational arithmetic in Python).
  EXPECT_NEAR(binomial_at_most(565, 600, 0.95), 0.1972208871357669, 1e-10);
  EXPECT_NEAR(binomial_at_most(560, 600, 0.95), 0.04204646458380411, 1e-10);
  EXPECT_NEAR(binomial_at_most(540, 600, 0.95), 4.1593809974578534e-07, 1e-15);
}

// A claim short by one piece of a few dozen is not evidence against it; one found at 80 %
// of 40 is. The text says which.
TEST(Sensitivity, ACheckSaysWhenItsShortfallIsEvidenceAgainstTheClaim) {
  SensitivityResult m;
  m.band_edges_mm = {0, 5, 10, 15, 20, 1000};
  m.cells = {{1, 3.0, 2, 15, 14}, {1, 3.0, 3, 40, 32}, {0, 2.0, 4, 30, 30}};
  const std::vector<SensitivityClaim> claims = {
      {1, 2, 10, 15, 3.0}, {1, 3, 15, 20, 3.0}, {0, 4, 20, 1000, 2.0}};
  const std::vector<ClaimCheck> k = check_claims(claims, m, 0.95);
  ASSERT_EQ(k.size(), 3u);
  EXPECT_FALSE(k[0].held);
  EXPECT_FALSE(k[0].contradicted);
  EXPECT_NEAR(k[0].p_at_rate, 1 - std::pow(0.95, 15), 1e-12);
  EXPECT_EQ(claim_check_text(k[0]),
            "needle 3.0 mm at 10-15 mm of meat: 14 of 15 found (93.3 %): NOT held; at a true "
            "95 % this few or fewer in 54 % of checks: no evidence against it");
  EXPECT_FALSE(k[1].held);
  EXPECT_TRUE(k[1].contradicted);
  EXPECT_NE(claim_check_text(k[1]).find("evidence against the claim"), std::string::npos);
  EXPECT_TRUE(k[2].held);
  EXPECT_EQ(claim_check_text(k[2]),
            "sphere 2.0 mm over 20 mm of meat: 30 of 30 found (100.0 %): held");
}

}  // namespace
}  // namespace rangex
