// Product learning: the GEV model and its fit against known parameters (and its fit to the
// upper tail against a mixture's exact rate), the component extreme against a threshold
// sweep, the per-thickness spread against its definition, learning from clean extremes
// (thresholds meet the budget on fillets it never saw; the confidence over many learning
// runs; the tail fit where the whole fit does not hold the learning's own top), refusal of a
// learning run with bone, drift, and the learned section's round trip.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <random>

#include "core/error.h"
#include "core/plant_config.h"
#include "pipeline/component_extreme.h"
#include "pipeline/connected_components.h"
#include "pipeline/gev_fit.h"
#include "pipeline/product_learning.h"
#include "pipeline/thickness_spread.h"

namespace rangex {
namespace {

GevModel truth_model() {
  GevModel g;
  g.m0 = 4.0, g.k_logn = 0.9, g.m_t = 0.04, g.s0 = std::log(0.5), g.s_t = 0.02, g.xi = 0.12;
  g.log_n_ref = std::log(8000.0), g.t_ref = 12;
  return g;
}

ExtremeSample draw(const GevModel& g, std::mt19937_64& rng, double n, double t) {
  std::uniform_real_distribution<double> u(1e-12, 1 - 1e-12);
  return {g.quantile(u(rng), n, t), n, t};
}

TEST(GevModel, QuantileInvertsCdfAndSurvivalHoldsInTheTail) {
  const GevModel g = truth_model();
  for (double p : {0.01, 0.3, 0.9, 0.999, 1 - 1e-7}) {
    const double x = g.quantile(p, 5000, 8);
    EXPECT_NEAR(g.cdf(x, 5000, 8), p, 1e-9 * std::max(1.0, 1 / (1 - p)));
    EXPECT_NEAR(std::exp(g.log_survival(x, 5000, 8)), 1 - p, 1e-6 * (1 - p));
  }
  GevModel gumbel = g;
  gumbel.xi = 0;
  EXPECT_NEAR(gumbel.cdf(gumbel.quantile(0.7, 100, 3), 100, 3), 0.7, 1e-12);
}

// The power of n is max-stability: the maximum of n pixels is distributed as the maximum of
// n_ref pixels raised to (n / n_ref)^k_logn. A model learned before (a location slope
// m_logn, no power) moves its location by m_logn per unit of ln n, as it did.
TEST(GevModel, ThePowerOfNIsMaxStabilityAndTheLocationSlopeStaysAsItWas) {
  GevModel g = truth_model();
  const double n_ref = std::exp(g.log_n_ref);
  for (double n : {0.3 * n_ref, 2.5 * n_ref})
    for (double x : {4.5, 6.0, 9.0})
      EXPECT_NEAR(g.cdf(x, n, 10), std::pow(g.cdf(x, n_ref, 10), std::pow(n / n_ref, g.k_logn)),
                  1e-12);
  GevModel before = g;
  before.k_logn = 0, before.m_logn = 0.45;
  EXPECT_NEAR(before.quantile(0.99, n_ref * std::exp(1.0), 10),
              before.quantile(0.99, n_ref, 10) + 0.45, 1e-12);
}

TEST(GevFit, RecoversKnownParametersWithCovariates) {
  const GevModel g = truth_model();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> n(1000, 20000), t(2, 26);
  std::vector<ExtremeSample> s;
  for (int i = 0; i < 3000; ++i) s.push_back(draw(g, rng, n(rng), t(rng)));
  const GevFit f = fit_gev(s);
  ASSERT_TRUE(f.converged);
  // The fit centres its covariates on the sample; compare where it matters: quantiles.
  for (double p : {0.5, 0.99, 0.999})
    for (double tt : {4.0, 12.0, 22.0})
      EXPECT_NEAR(f.model.quantile(p, 8000, tt), g.quantile(p, 8000, tt),
                  0.05 * g.quantile(p, 8000, tt))
          << "p " << p << " t " << tt;
  EXPECT_NEAR(f.model.xi, g.xi, 0.05);
  EXPECT_NEAR(f.model.k_logn, g.k_logn, 0.1);
  EXPECT_EQ(f.model.m_logn, 0.0);
}

// The tail fit follows the upper tail where the bulk is another population: extremes of a
// product with a second population in its top (in one band of twenty a lump denser than
// meat, whose extreme spreads twice as wide as the texture's), a band's extreme the larger
// of the two, so that the rate at any threshold is known exactly. Fitted to every extreme,
// the bulk holds the model to the texture's spread and it promises 35-40 % fewer false
// rejects than happen at far thresholds; fitted above the whole fit's median, within 10 %.
// On the texture alone the two fits agree with the truth.
TEST(GevFit, TheTailFitFollowsTheTopWhereTheBulkIsAnotherPopulation) {
  GevModel tex;
  tex.m0 = 4.0, tex.s0 = std::log(0.5), tex.xi = 0.02, tex.log_n_ref = std::log(8000.0);
  tex.t_ref = 12, tex.k_logn = 1;
  GevModel lump = tex;
  lump.m0 = 5.0, lump.s0 = std::log(1.0), lump.xi = 0;
  const double share = 0.05;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<ExtremeSample> mixed, pure;
  for (int i = 0; i < 3000; ++i) {
    ExtremeSample e = draw(tex, rng, 8000, 12);
    pure.push_back(e);
    if (u(rng) < share) e.x = std::max(e.x, draw(lump, rng, 8000, 12).x);
    mixed.push_back(e);
  }
  auto survival = [](const GevFit& f, double x) {
    return std::exp(f.model.log_survival(x, 8000, 12));
  };
  auto mixed_survival = [&](double x) {
    return -std::expm1(std::log(tex.cdf(x, 8000, 12)) +
                       std::log((1 - share) + share * lump.cdf(x, 8000, 12)));
  };
  GevFitOptions tail;
  tail.tail_from = 0.5;
  const GevFit whole = fit_gev(mixed), top = fit_gev(mixed, tail);
  ASSERT_TRUE(whole.converged && top.converged);
  EXPECT_EQ(whole.tail_from, 0.0);
  EXPECT_EQ(top.tail_from, 0.5);
  EXPECT_EQ(top.whole.m0, whole.model.m0);  // the fit that censored it
  for (double x : {9.0, 11.0}) {
    const double truth = mixed_survival(x);
    EXPECT_LT(survival(whole, x), 0.7 * truth) << x;
    EXPECT_GT(survival(top, x), 0.9 * truth) << x;
    EXPECT_LT(survival(top, x), 1.15 * truth) << x;
  }
  const GevFit whole_pure = fit_gev(pure), top_pure = fit_gev(pure, tail);
  for (double x : {6.0, 7.0}) {
    const double truth = std::exp(tex.log_survival(x, 8000, 12));
    EXPECT_NEAR(survival(whole_pure, x), truth, 0.2 * truth) << x;
    EXPECT_NEAR(survival(top_pure, x), truth, 0.2 * truth) << x;
  }
}

TEST(GevFit, LocationShiftIsFound) {
  const GevModel g = truth_model();
  std::mt19937_64 rng(5);
  std::vector<ExtremeSample> s;
  GevModel moved = g;
  moved.m0 += 0.8;
  for (int i = 0; i < 600; ++i) s.push_back(draw(moved, rng, 8000, 12));
  EXPECT_NEAR(fit_location_shift(g, s), 0.8, 0.08);
}

TEST(ComponentExtreme, EqualsTheHighestThresholdWithALargeEnoughComponent) {
  std::mt19937_64 rng(11);
  std::normal_distribution<float> nd;
  const int R = 40, C = 50;
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<float> v(size_t(R) * C);
    std::vector<uint8_t> use(v.size());
    for (size_t i = 0; i < v.size(); ++i) v[i] = nd(rng), use[i] = (i % 7) != 0;
    for (int min_px : {1, 2, 4}) {
      const double x = component_extreme(v.data(), use.data(), R, C, min_px);
      // Brute force: above x - eps a large enough component exists, above x + eps none.
      auto exists = [&](double t) {
        std::vector<uint8_t> on(v.size());
        for (size_t i = 0; i < v.size(); ++i) on[i] = use[i] && v[i] > t;
        std::vector<int> labels;
        for (const Component& c : label_components(on.data(), R, C, labels))
          if (c.pixels >= min_px) return true;
        return false;
      };
      EXPECT_TRUE(exists(x - 1e-6)) << "trial " << trial << " min " << min_px;
      EXPECT_FALSE(exists(x)) << "trial " << trial << " min " << min_px;
    }
  }
}

TEST(ThicknessSpread, UnitSpreadInEveryThicknessRangeDespiteHeavyTails) {
  // Noise whose spread grows with thickness (sigma = 0.5 + 0.1 T), 2 % gross outliers.
  std::mt19937_64 rng(7);
  std::normal_distribution<double> nd;
  std::uniform_real_distribution<double> ut(1, 25), uo(0, 1);
  const size_t n = 60000;
  std::vector<float> t(n), v(n);
  std::vector<uint8_t> use(n, 1);
  for (size_t i = 0; i < n; ++i) {
    t[i] = float(ut(rng));
    v[i] = float(0.3 + (0.5 + 0.1 * t[i]) * nd(rng) + (uo(rng) < 0.02 ? 30 : 0));
  }
  const ThicknessBins bins = thickness_bins(t.data(), use.data(), n);
  EXPECT_EQ(bins.members.size(), 8u);
  unit_spread_by_thickness(v, t.data(), use.data(), bins, 0.0);
  for (double lo : {2.0, 8.0, 14.0, 20.0}) {
    std::vector<double> in;
    for (size_t i = 0; i < n; ++i)
      if (t[i] >= lo && t[i] < lo + 3) in.push_back(v[i]);
    std::sort(in.begin(), in.end());
    const double med = in[in.size() / 2];
    for (double& x : in) x = std::abs(x - med);
    std::sort(in.begin(), in.end());
    EXPECT_NEAR(in[in.size() / 2] / 0.6745, 1.0, 0.08) << "thickness " << lo;
    EXPECT_NEAR(med, 0.0, 0.08) << "thickness " << lo;
  }
}

// Thickness in steps of 0.5 mm (runs of ties across the bins' edges), unusable and unmeasured
// pixels: every usable measured pixel in one bin, equal counts, the bins in thickness order,
// each centre its middle pixel's thickness.
TEST(ThicknessSpread, BinsHoldEveryPixelOnceInThicknessOrderWithTies) {
  std::mt19937_64 rng(3);
  std::uniform_int_distribution<int> step(2, 50);
  const size_t n = 40001;
  std::vector<float> t(n);
  std::vector<uint8_t> use(n, 1);
  for (size_t i = 0; i < n; ++i) {
    t[i] = 0.5f * float(step(rng));
    if (i % 17 == 0) use[i] = 0;
    if (i % 29 == 0) t[i] = std::numeric_limits<float>::quiet_NaN();
  }
  const ThicknessBins bins = thickness_bins(t.data(), use.data(), n);
  ASSERT_EQ(bins.members.size(), 8u);
  std::vector<int> seen(n, 0);
  size_t usable = 0;
  for (size_t i = 0; i < n; ++i) usable += use[i] && std::isfinite(t[i]);
  float last = -1;
  for (size_t k = 0; k < bins.members.size(); ++k) {
    const std::vector<size_t>& m = bins.members[k];
    EXPECT_LE(m.size(), usable / 8 + 1);
    EXPECT_GE(m.size(), usable / 8);
    std::vector<float> ts;
    for (size_t i : m) {
      ASSERT_LT(i, n);
      EXPECT_TRUE(use[i] && std::isfinite(t[i]));
      ++seen[i];
      ts.push_back(t[i]);
    }
    EXPECT_TRUE(std::is_sorted(ts.begin(), ts.end())) << "bin " << k;
    EXPECT_GE(ts.front(), last) << "bin " << k;
    last = ts.back();
    EXPECT_EQ(bins.centre_mm[k], double(ts[ts.size() / 2])) << "bin " << k;
  }
  for (size_t i = 0; i < n; ++i) EXPECT_EQ(seen[i], use[i] && std::isfinite(t[i]) ? 1 : 0) << i;
}

// One bin (one spread per fillet; or a fillet too small for two): every usable measured pixel
// once, in image order, its centre the thickness at the middle rank of the sorted values (what
// the bins in thickness order give), with ties, an even and an odd count.
TEST(ThicknessSpread, OneBinHoldsEveryPixelInImageOrderAndTheMiddleThickness) {
  for (const size_t n : {40001u, 40002u, 5000u}) {
    std::mt19937_64 rng(5 + n);
    std::uniform_int_distribution<int> step(2, 50);
    std::vector<float> t(n);
    std::vector<uint8_t> use(n, 1);
    for (size_t i = 0; i < n; ++i) {
      t[i] = 0.5f * float(step(rng));
      if (i % 13 == 0) use[i] = 0;
      if (i % 31 == 0) t[i] = std::numeric_limits<float>::quiet_NaN();
    }
    std::vector<size_t> want;
    std::vector<float> sorted;
    for (size_t i = 0; i < n; ++i)
      if (use[i] && std::isfinite(t[i])) want.push_back(i), sorted.push_back(t[i]);
    std::sort(sorted.begin(), sorted.end());
    // n = 5000: the default 3,000 pixels a bin leave room for one only.
    const ThicknessBins bins = n == 5000 ? thickness_bins(t.data(), use.data(), n)
                                         : thickness_bins(t.data(), use.data(), n, 1);
    ASSERT_EQ(bins.members.size(), 1u) << n;
    EXPECT_EQ(bins.members[0], want) << n;
    EXPECT_EQ(bins.centre_mm[0], double(sorted[sorted.size() / 2])) << n;
  }
  std::vector<float> t(10, 3.f);
  std::vector<uint8_t> none(10, 0);
  EXPECT_TRUE(thickness_bins(t.data(), none.data(), 10, 1).members.empty());
}

// Statistic s's extremes in the fillets below: g moved up by 0.3 s.
GevModel stat_model(const GevModel& g, int s) {
  GevModel gs = g;
  gs.m0 += 0.3 * s;
  return gs;
}

// Learning fillets with 3-5 bands of 5 mm, each statistic's band extreme drawn over 2,000-
// 14,000 pixels by draw(rng, stat, pixels, thickness) -> {extreme, pixels it stands for}.
using ExtremeDraw = std::function<std::pair<double, double>(std::mt19937_64&, int, double, double)>;
std::vector<LearningFillet> fillets_drawn(int count, uint64_t seed, const ExtremeDraw& draw) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> n(2000, 14000);
  std::uniform_int_distribution<int> top(3, 5);
  std::vector<LearningFillet> out;
  for (int i = 0; i < count; ++i) {
    LearningFillet f;
    f.id = i;
    f.y0_mm = 300.0 * i;
    const int bands = top(rng);
    for (int b = 0; b < bands; ++b)
      for (int s = 0; s < kStatistics; ++s) {
        const double pixels = n(rng), t = 5.0 * b + 2.5;
        const auto [x, used] = draw(rng, s, pixels, t);
        f.extremes.push_back({s, b, x, used, t});
      }
    out.push_back(f);
  }
  return out;
}

// Learning fillets whose band extremes follow `g`.
std::vector<LearningFillet> clean_fillets(const GevModel& g, int count, uint64_t seed) {
  return fillets_drawn(count, seed, [&](std::mt19937_64& rng, int s, double n, double t) {
    return std::pair{draw(stat_model(g, s), rng, n, t).x, n};
  });
}

// The per-fillet rate of fillets with a rejecting statistic above its band's threshold.
double false_reject_rate(const LearnedDetection& L, const std::vector<LearningFillet>& fs) {
  int rejected = 0;
  for (const auto& f : fs) {
    bool rej = false;
    for (const BandExtreme& e : f.extremes)
      rej = rej || (e.stat != kStatAir && e.x > L.stats[size_t(e.stat)].thresholds[size_t(e.band)]);
    rejected += rej;
  }
  return double(rejected) / double(fs.size());
}

TEST(ProductLearning, ThresholdsMeetTheBudgetOnFilletsItNeverSaw) {
  const GevModel g = truth_model();
  LearnOptions o;
  o.target_frr = 0.01;
  o.bootstrap = 60;
  const ProductLearning L = learn_product(clean_fillets(g, 60, 1), o);
  ASSERT_TRUE(L.ok) << (L.problems.empty() ? "" : L.problems[0]);
  EXPECT_EQ(L.fillets, 60);
  EXPECT_TRUE(L.flagged.empty());
  // 20 000 new fillets of the same product.
  const double frr = false_reject_rate(L.learned, clean_fillets(g, 20000, 99));
  EXPECT_LE(frr, o.target_frr * 1.2);
  EXPECT_GE(frr, o.target_frr * 0.05);  // not bought with blindness
  // The learned extremes follow their model (the QQ plot's test).
  EXPECT_GT(L.stats[kStatRound].ks_p, 0.01);
  // Exact with fixed seeds.
  const ProductLearning again = learn_product(clean_fillets(g, 60, 1), o);
  EXPECT_EQ(again.learned.stats[kStatRound].thresholds, L.learned.stats[kStatRound].thresholds);
}

// The rate at which fillets laid out as `layout` (bands and pixels; their drawn extremes are
// not used) exceed the thresholds, given ln P(a band's extreme <= threshold): exact given the
// layout.
using LogPass = std::function<double(const BandExtreme&, double threshold)>;
double exact_false_reject_rate(const LearnedDetection& L, const std::vector<LearningFillet>& layout,
                               const LogPass& log_pass) {
  double sum = 0;
  for (const auto& f : layout) {
    double log_pass_all = 0;
    for (const BandExtreme& e : f.extremes)
      if (e.stat != kStatAir)
        log_pass_all += log_pass(e, L.stats[size_t(e.stat)].thresholds[size_t(e.band)]);
    sum += -std::expm1(log_pass_all);
  }
  return sum / double(layout.size());
}

// 30 learning runs of 40 fillets (learning fillets of run k: fillets(k)), each run's rate
// computed exactly: how many runs learned, how many met the default target (0.3 % at 90 %
// confidence), and the median share of the target they spent.
struct Coverage {
  int learned = 0, met = 0;
  double median_spent = 0;
};
Coverage confidence_coverage(const std::function<std::vector<LearningFillet>(int)>& fillets,
                             const std::function<double(const LearnedDetection&)>& rate) {
  Coverage c;
  std::vector<double> spent;
  for (int k = 0; k < 30; ++k) {
    LearnOptions o;  // target 0.003, confidence 0.9, 100 resamples
    o.seed = 100 + uint64_t(k);
    const ProductLearning L = learn_product(fillets(k), o);
    // A heavy tail now and then names a clean fillet (an operator would check it and keep
    // it in). Those runs say nothing of the confidence.
    if (!L.ok) continue;
    ++c.learned;
    const double frr = rate(L.learned);
    c.met += frr <= o.target_frr;
    spent.push_back(frr / o.target_frr);
  }
  if (!spent.empty()) {
    std::sort(spent.begin(), spent.end());
    c.median_spent = spent[spent.size() / 2];
  }
  std::printf(
      "learning runs whose thresholds meet the target: %d of %d; median share of the target "
      "spent %.3f\n",
      c.met, c.learned, c.median_spent);
  return c;
}

// "The thresholds meet 0.3 % with 90 % confidence", said of 40 fillets, is a statement
// about learning runs: of many runs of the same product, about 90 % learn thresholds that
// meet the target. Checked on a known product, with the rate each run's thresholds really
// let through (exact given 4000 fillets' layouts). And they spend a fair part of the target:
// a confidence bought with blindness would pass this by rejecting nothing.
TEST(ProductLearning, TheConfidenceIsTheShareOfLearningRunsWhoseThresholdsMeetTheTarget) {
  const GevModel g = truth_model();
  const auto layout = clean_fillets(g, 4000, 77);
  const Coverage c = confidence_coverage(
      [&](int k) { return clean_fillets(g, 40, 1000 + uint64_t(k)); },
      [&](const LearnedDetection& L) {
        return exact_false_reject_rate(L, layout, [&](const BandExtreme& e, double thr) {
          return std::log(stat_model(g, e.stat).cdf(thr, e.n, e.t));
        });
      });
  ASSERT_GE(c.learned, 24);  // 80 % of the runs
  // 27 runs cannot tell 85 % from 90 %; they tell it from the 50 % of thresholds learned at
  // 50 % confidence (13 of 27 met the target so).
  EXPECT_GE(c.met, int(0.8 * c.learned));
  EXPECT_GT(c.median_spent, 0.1);
}

// Bands of n independent pixels with a heavy (generalised Pareto) tail whose scale grows
// with the thickness: a band's largest pixel drawn exactly, so the rate any threshold lets
// through is known exactly, P(band passes) = F(threshold)^n. The GEV regression is the
// model's approximation, as for real meat; this is the truth it approximates.
struct PixelTail {
  double xi = 0.12, b = 0.5, shift = 0;
  double scale(double t) const { return b * std::exp(0.02 * (t - 12)); }
  double quantile_upper(double u_upper, double t) const {  // u_upper = 1 - F
    return shift + scale(t) * (std::pow(u_upper, -xi) - 1) / xi;
  }
  double log_cdf(double x, double t) const {
    const double y = std::max(0.0, (x - shift) / scale(t));
    return std::log1p(-std::pow(1 + xi * y, -1 / xi));
  }
};
PixelTail pixel_tail(int stat) {
  return {0.12, 0.5, 0.3 * stat};
}

std::vector<LearningFillet> pixel_fillets(int count, uint64_t seed) {
  return fillets_drawn(count, seed, [](std::mt19937_64& rng, int s, double n, double t) {
    std::uniform_real_distribution<double> u(1e-300, 1);
    const double pixels = std::floor(n);
    // The largest of n uniforms is V^(1/n): 1 - U(n) = -expm1(ln V / n).
    return std::pair{pixel_tail(s).quantile_upper(-std::expm1(std::log(u(rng)) / pixels), t),
                     pixels};
  });
}

// The confidence's promise where the extremes are maxima of heavy-tailed pixels: the
// maximum of n such pixels has a scale that grows with n (n^xi), which a location slope in
// ln n alone cannot follow; the model's max-stable power of n does (core/gev_model.h).
// Measured 2026-12-01 on these 30 runs: with the location slope, 22 of 27 learning runs met
// the target (median share spent 0.31); with the power of n, 23 of 26 (0.34). (On another
// draw of the same product, 20 of 28 and 25 of 28.)
TEST(ProductLearning, TheConfidenceHoldsForMaximaOfHeavyTailedPixels) {
  const auto layout = pixel_fillets(4000, 77);
  const Coverage c = confidence_coverage(
      [](int k) { return pixel_fillets(40, 2000 + uint64_t(k)); },
      [&](const LearnedDetection& L) {
        return exact_false_reject_rate(L, layout, [](const BandExtreme& e, double thr) {
          return e.n * pixel_tail(e.stat).log_cdf(thr, e.t);
        });
      });
  ASSERT_GE(c.learned, 24);  // 80 % of the runs
  EXPECT_GE(c.met, int(0.8 * c.learned));
  EXPECT_GT(c.median_spent, 0.1);
}

// Which fit a statistic gets: the whole fit where it holds the learning's own top extremes,
// the tail fit where more of them lie above its 99 % quantile than chance gives (a product
// with a second population in its top: in one band of twenty a lump denser than meat, whose
// extreme spreads twice as wide as the texture's and sits above its bulk).
std::vector<LearningFillet> lumpy_fillets(int count, uint64_t seed) {
  return fillets_drawn(count, seed, [](std::mt19937_64& rng, int s, double n, double t) {
    GevModel tex = stat_model(truth_model(), s);
    tex.xi = -0.1;  // bounded, as the texture of smooth meat fits
    double x = draw(tex, rng, n, t).x;
    std::uniform_real_distribution<double> u(0, 1);
    if (u(rng) < 0.06) {
      GevModel lump = tex;
      lump.m0 += 2.5, lump.s0 += std::log(2.0);
      lump.xi = 0, lump.k_logn = 0;
      x = std::max(x, draw(lump, rng, n, t).x);
    }
    return std::pair{x, n};
  });
}

TEST(ProductLearning, AStatisticWhoseTopTheWholeFitDoesNotHoldIsFittedToItsTail) {
  LearnOptions o;
  o.bootstrap = 20;
  LearnOptions never = o;
  never.tail_from = 0;
  const ProductLearning plain = learn_product(clean_fillets(truth_model(), 40, 8), o);
  const ProductLearning plain_whole = learn_product(clean_fillets(truth_model(), 40, 8), never);
  const ProductLearning lumpy = learn_product(lumpy_fillets(40, 8), o);
  const ProductLearning lumpy_whole = learn_product(lumpy_fillets(40, 8), never);
  ASSERT_TRUE(plain.ok && plain_whole.ok && lumpy.ok && lumpy_whole.ok);
  int tails = 0;
  for (int s : {kStatRound, kStatNeedle}) {
    // Without a second population the whole fit holds its top and stays, to the digit.
    const StatisticLearning& p = plain.stats[size_t(s)];
    EXPECT_GE(p.top_p, o.tail_alpha) << statistic_name(s);
    EXPECT_EQ(plain.learned.stats[size_t(s)].tail_from, 0.0);
    EXPECT_EQ(plain.learned.stats[size_t(s)].thresholds,
              plain_whole.learned.stats[size_t(s)].thresholds);
    // With it, a statistic whose top exceeds the whole fit's 99 % more than chance gives is
    // fitted to its tail, and its thresholds rise; one whose top does not is left as it was.
    const StatisticLearning& l = lumpy.stats[size_t(s)];
    const std::vector<double>& t = lumpy.learned.stats[size_t(s)].thresholds;
    const std::vector<double>& w = lumpy_whole.learned.stats[size_t(s)].thresholds;
    const bool tail = l.top_p < o.tail_alpha;
    tails += tail;
    EXPECT_EQ(lumpy.learned.stats[size_t(s)].tail_from, tail ? 0.5 : 0.0) << statistic_name(s);
    if (tail) {
      EXPECT_GT(l.top_above, 2 * kTopShare * l.samples);
      for (size_t b = 0; b < t.size(); ++b) EXPECT_GT(t[b], w[b]) << statistic_name(s) << b;
    } else {
      EXPECT_EQ(t, w);
    }
    EXPECT_EQ(lumpy_whole.stats[size_t(s)].top_above, -1);  // not checked with it off
  }
  EXPECT_GE(tails, 1);
  EXPECT_EQ(lumpy.stats[kStatAir].top_above, -1);  // air pockets never reject
}

TEST(ProductLearning, ALearningRunWithBoneFailsNamingTheFillets) {
  auto fs = clean_fillets(truth_model(), 40, 2);
  // Bones stand out by 10-50 (smoothed z); a heavy-tailed product hides weaker ones.
  fs[7].extremes[0].x = 30;   // round statistic, band 0
  fs[23].extremes[4].x = 25;  // needle, band 1
  LearnOptions o;
  o.bootstrap = 20;
  const ProductLearning L = learn_product(fs, o);
  EXPECT_FALSE(L.ok);
  ASSERT_EQ(L.flagged.size(), 2u);
  std::vector<int64_t> ids = {L.flagged[0].id, L.flagged[1].id};
  std::sort(ids.begin(), ids.end());
  EXPECT_EQ(ids, (std::vector<int64_t>{7, 23}));
  bool named = false;
  for (const auto& p : L.problems) named = named || p.find("fillet 7 ") != std::string::npos;
  EXPECT_TRUE(named);
  EXPECT_EQ(L.fillets, 38);
}

TEST(ProductLearning, AFilletCheckedCleanIsKeptAndTheThresholdsRiseOverIt) {
  // The run above, with fillet 7 looked at by an operator and found clean (cartilage, say).
  auto fs = clean_fillets(truth_model(), 40, 2);
  fs[7].extremes[0].x = 30;
  fs[23].extremes[4].x = 25;
  LearnOptions o;
  o.bootstrap = 20;
  const ProductLearning without = learn_product(fs, o);
  o.checked_clean = {{0, 7}};
  const ProductLearning L = learn_product(fs, o);
  EXPECT_FALSE(L.ok);  // fillet 23 still holds something like bone
  ASSERT_EQ(L.flagged.size(), 1u);
  EXPECT_EQ(L.flagged[0].id, 23);
  ASSERT_EQ(L.kept.size(), 1u);
  EXPECT_EQ(L.kept[0].id, 7);
  EXPECT_DOUBLE_EQ(L.kept[0].x, 30);
  EXPECT_EQ(L.fillets, 39);
  // Its extreme is now the product's: the round thresholds rise over it.
  EXPECT_GT(L.learned.stats[kStatRound].thresholds[0],
            without.learned.stats[kStatRound].thresholds[0]);
  o.checked_clean = {{0, 7}, {0, 23}};
  const ProductLearning both = learn_product(fs, o);
  EXPECT_TRUE(both.ok) << (both.problems.empty() ? "" : both.problems[0]);
  EXPECT_TRUE(both.flagged.empty());
  EXPECT_EQ(both.kept.size(), 2u);
  EXPECT_EQ(both.fillets, 40);
  // A fillet named that the run does not hold fails the learning, naming it.
  o.checked_clean = {{0, 7}, {2, 7}};
  const ProductLearning wrong = learn_product(fs, o);
  EXPECT_FALSE(wrong.ok);
  bool named = false;
  for (const auto& p : wrong.problems)
    named = named || p.find("lane 2 fillet 7, checked clean, is not in the learning run") !=
                         std::string::npos;
  EXPECT_TRUE(named);
}

TEST(ProductLearning, TooFewFilletsFails) {
  LearnOptions o;
  o.bootstrap = 20;
  const ProductLearning L = learn_product(clean_fillets(truth_model(), 20, 4), o);
  EXPECT_FALSE(L.ok);
  ASSERT_FALSE(L.problems.empty());
  EXPECT_NE(L.problems[0].find("too few clean fillets: 20 of the 30"), std::string::npos);
}

// A handful of fillets whose extremes have a tail as heavy as the fit allows: its quantile
// for the budget lies beyond any statistic (a live lane learned 1e15 from 3 fillets, and
// stored settings that did not read back). The learning fails saying so, and what it writes
// still reads back.
TEST(ProductLearning, ATailTooHeavyForAThresholdFailsAndStillReadsBack) {
  GevModel g = truth_model();
  g.s0 = std::log(5000.0), g.xi = 0.6;
  LearnOptions o;
  o.bootstrap = 20;
  o.min_fillets = 5;
  const ProductLearning L = learn_product(clean_fillets(g, 6, 12), o);
  EXPECT_FALSE(L.ok);
  bool said = false;
  for (const std::string& p : L.problems)
    said = said || p.find("sets no usable threshold") != std::string::npos;
  EXPECT_TRUE(said) << (L.problems.empty() ? "" : L.problems[0]);
  for (const LearnedStatistic& st : L.learned.stats)
    for (double t : st.thresholds) EXPECT_LT(t, kMaxLearnedThreshold);
  LearnedDetection copy = L.learned;
  copy.version = "heavy";
  const LearnedDetection back = parse_learned_detection(learned_detection_yaml(copy), "test");
  EXPECT_EQ(back.stats[kStatRound].thresholds.size(), copy.stats[kStatRound].thresholds.size());
}

TEST(ProductLearning, DriftOfARougherProductIsSeenAndTheSameProductIsNot) {
  const GevModel g = truth_model();
  LearnOptions o;
  o.bootstrap = 40;
  const ProductLearning L = learn_product(clean_fillets(g, 60, 5), o);
  ASSERT_TRUE(L.ok);
  // What a lane tracks: the fillets it passed (no rejecting extreme above its threshold).
  auto recent = [&](const GevModel& m, uint64_t seed) {
    std::vector<std::vector<BandExtreme>> r;
    for (const auto& f : clean_fillets(m, 400, seed)) {
      bool passed = true;
      for (const BandExtreme& e : f.extremes)
        passed = passed && (e.stat == kStatAir ||
                            e.x <= L.learned.stats[size_t(e.stat)].thresholds[size_t(e.band)]);
      if (passed && r.size() < 200) r.push_back(f.extremes);
    }
    return r;
  };
  const DriftEstimate same = estimate_drift(L.learned, recent(g, 6));
  EXPECT_LT(same.implied_frr, 2 * o.target_frr);
  GevModel rough = g;
  rough.m0 += 3.5;
  const DriftEstimate drift = estimate_drift(L.learned, recent(rough, 7));
  EXPECT_NEAR(drift.shift[kStatRound], 3.5, 0.3);
  EXPECT_NEAR(drift.shift[kStatNeedle], 3.5, 0.3);
  // What 200 fillets imply is what the rougher product really does (20 000 of them).
  const double real = false_reject_rate(L.learned, clean_fillets(rough, 20000, 8));
  EXPECT_NEAR(drift.implied_frr, real, 0.35 * real);
  EXPECT_GT(real, 2 * o.target_frr);
  EXPECT_GT(drift.implied_frr, 2 * o.target_frr);
}

// A statistic fitted to its tail is followed where it was fitted: the drift monitor counts a
// passed fillet's extreme at or below the whole fit's median as lying there. The same lumpy
// product stays quiet; moved up by 4.5 (a rougher product, which really rejects 2.0 %), it is
// flagged. The refit reads it low (0.78 %, measured 2026-12-04): one GEV follows a mixture's
// top only so far, and the lumps that stay under the thresholds say little of those above.
TEST(ProductLearning, DriftFollowsATailFitAboveItsLevel) {
  LearnOptions o;
  o.bootstrap = 40;
  const ProductLearning L = learn_product(lumpy_fillets(60, 5), o);
  ASSERT_TRUE(L.ok);
  ASSERT_TRUE(L.learned.stats[kStatRound].tail_from > 0 ||
              L.learned.stats[kStatNeedle].tail_from > 0);
  auto recent = [&](double shift, uint64_t seed) {
    std::vector<std::vector<BandExtreme>> r;
    for (auto f : lumpy_fillets(600, seed)) {
      bool passed = true;
      for (BandExtreme& e : f.extremes) {
        e.x += shift;
        passed = passed && (e.stat == kStatAir ||
                            e.x <= L.learned.stats[size_t(e.stat)].thresholds[size_t(e.band)]);
      }
      if (passed && r.size() < 200) r.push_back(f.extremes);
    }
    return r;
  };
  const DriftEstimate same = estimate_drift(L.learned, recent(0, 6));
  EXPECT_LT(same.implied_frr, 2 * o.target_frr);
  const DriftEstimate rough = estimate_drift(L.learned, recent(4.5, 7));
  auto shifted = lumpy_fillets(20000, 8);
  for (auto& f : shifted)
    for (BandExtreme& e : f.extremes) e.x += 4.5;
  EXPECT_GT(false_reject_rate(L.learned, shifted), 2 * o.target_frr);
  EXPECT_GT(rough.implied_frr, 2 * o.target_frr);
  EXPECT_NEAR(rough.shift[kStatRound], 4.5, 0.4);
}

// A few small bands (150 pixels) whose extremes lie deep in the learned model's lower tail,
// as the thin ends of fillets put them (a recorded plant's 6 of 1,224): the same product,
// and the monitor says so. Counted with their density, they widened the refit's scale and
// implied 3.6 times the false rejects of the same fillets without them (on the recorded
// plant, five times what it had learned).
TEST(ProductLearning, DriftIsNotRaisedBySmallBandsDeepInTheLowerTail) {
  GevModel g = truth_model();
  g.xi = 0;  // a Gumbel tail, as the plant's: its refit can only widen
  LearnOptions o;
  o.bootstrap = 40;
  const ProductLearning L = learn_product(clean_fillets(g, 60, 5), o);
  ASSERT_TRUE(L.ok);
  std::vector<std::vector<BandExtreme>> plain, with_lows;
  for (const auto& f : clean_fillets(g, 400, 6)) {
    bool passed = true;
    for (const BandExtreme& e : f.extremes)
      passed = passed && (e.stat == kStatAir ||
                          e.x <= L.learned.stats[size_t(e.stat)].thresholds[size_t(e.band)]);
    if (!passed || plain.size() == 200) continue;
    plain.push_back(f.extremes);
    std::vector<BandExtreme> ex = f.extremes;
    if (plain.size() % 20 == 0) {
      int top = 0;
      for (const BandExtreme& e : ex) top = std::max(top, e.band);
      const double n = 150, t = 5.0 * (top + 1) + 2.5;
      for (int s = 0; s < kStatistics; ++s)
        ex.push_back({s, top + 1, stat_model(g, s).quantile(1e-12, n, t), n, t});
    }
    with_lows.push_back(ex);
  }
  ASSERT_EQ(with_lows.size(), 200u);
  const DriftEstimate same = estimate_drift(L.learned, plain);
  const DriftEstimate lows = estimate_drift(L.learned, with_lows);
  EXPECT_LT(lows.implied_frr, 2 * o.target_frr);
  EXPECT_NEAR(lows.implied_frr, same.implied_frr, 0.25 * same.implied_frr);
  EXPECT_NEAR(lows.shift[kStatRound], same.shift[kStatRound], 0.05);
}

TEST(LearnedDetection, RoundTripsThroughItsYamlAndRefusesBadValues) {
  LearnOptions o;
  o.bootstrap = 20;
  ProductLearning L = learn_product(clean_fillets(truth_model(), 40, 8), o);
  L.learned.version = "v \"quoted\"";
  L.learned.learned_on = "rec lane 0";
  EXPECT_FALSE(L.learned.rim_walls);  // as the options said
  L.learned.rim_walls = true;
  const std::string y = learned_detection_yaml(L.learned);
  const LearnedDetection back = parse_learned_detection(y, "test");
  EXPECT_EQ(back.version, L.learned.version);
  EXPECT_TRUE(back.rim_walls);
  // Settings learned before the outline's wall was carried read without it.
  std::string old_rim = y;
  old_rim.erase(old_rim.find("rim_walls: true\n"), 16);
  EXPECT_FALSE(parse_learned_detection(old_rim, "test").rim_walls);
  EXPECT_EQ(back.band_edges_mm, L.learned.band_edges_mm);
  for (int s = 0; s < kStatistics; ++s) {
    for (size_t b = 0; b < back.stats[s].thresholds.size(); ++b)
      EXPECT_NEAR(back.stats[s].thresholds[b], L.learned.stats[s].thresholds[b], 1e-9);
    EXPECT_NEAR(back.stats[s].model.xi, L.learned.stats[s].model.xi, 1e-9);
    EXPECT_NEAR(back.stats[s].model.k_logn, L.learned.stats[s].model.k_logn, 1e-6);
    EXPECT_NEAR(back.stats[s].model.quantile(0.999, 3000, 7),
                L.learned.stats[s].model.quantile(0.999, 3000, 7), 1e-5);
  }
  // A tail fit keeps its level and the whole fit that set it; the drift monitor censors
  // there too. Settings learned before it read as fitted to every extreme, and a tail
  // without the fit that set its level is refused.
  {
    LearnOptions always = o;
    always.tail_alpha = 1.1;  // every rejecting statistic fitted to its tail
    const LearnedDetection t = learn_product(clean_fillets(truth_model(), 40, 8), always).learned;
    const LearnedDetection tb = parse_learned_detection(learned_detection_yaml(t), "test");
    for (int s = 0; s < kStatistics; ++s) {
      const double expected = s == kStatAir ? 0.0 : 0.5;  // air pockets never reject
      EXPECT_EQ(t.stats[s].tail_from, expected);
      EXPECT_EQ(tb.stats[s].tail_from, expected);
      EXPECT_NEAR(tb.stats[s].whole_model.quantile(0.5, 3000, 7),
                  t.stats[s].whole_model.quantile(0.5, 3000, 7), 1e-5);
      EXPECT_NEAR(tb.stats[s].model.quantile(0.999, 3000, 7),
                  t.stats[s].model.quantile(0.999, 3000, 7), 1e-5);
    }
    std::string no_whole = learned_detection_yaml(t);
    const size_t at = no_whole.find("\n  whole_model: {");
    ASSERT_NE(at, std::string::npos);
    no_whole.erase(at, no_whole.find('}', at) + 1 - at);
    try {
      parse_learned_detection(no_whole, "x.yaml");
      FAIL() << "accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("whole_model"), std::string::npos) << e.what();
    }
  }
  {
    LearnedDetection whole = L.learned;
    for (auto& st : whole.stats) st.tail_from = 0;
    const std::string w = learned_detection_yaml(whole);
    EXPECT_EQ(w.find("tail_from"), std::string::npos);
    EXPECT_EQ(parse_learned_detection(w, "t").stats[kStatRound].tail_from, 0.0);
  }
  // A model learned before the power of n reads as it was: its location slope, no power.
  std::string before = y;
  const size_t k = before.find(", k_logn: ");
  ASSERT_NE(k, std::string::npos);
  before.erase(k, before.find('}', k) - k);
  const GevModel old_model = parse_learned_detection(before, "t").stats[kStatRound].model;
  EXPECT_EQ(old_model.k_logn, 0.0);
  // A statistic whose extremes reach thousands (air pockets at steep walls did) reads back
  // as it was written.
  LearnedDetection huge = L.learned;
  for (double& t : huge.stats[kStatAir].thresholds) t = 1852.95;
  EXPECT_NEAR(
      parse_learned_detection(learned_detection_yaml(huge), "t").stats[kStatAir].thresholds.at(0),
      1852.95, 1e-9);
  std::string bad = y;
  bad.replace(bad.find("thresholds: [") + 13, 0, "-1, ");
  try {
    parse_learned_detection(bad, "x.yaml");
    FAIL() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("round.thresholds"), std::string::npos) << e.what();
  }
  const std::string plant =
      "lanes:\n  - id: 0\n    inspection:\n      false_reject_target: 0.01\n"
      "      learned:\n" +
      [&] {
        std::string ind;
        std::istringstream in(y);
        std::string line;
        while (std::getline(in, line)) ind += "        " + line + "\n";
        return ind;
      }();
  const PlantConfig p = parse_plant_config(plant, "plant.yaml");
  EXPECT_TRUE(p.lanes[0].inspection.learned.active());
  EXPECT_DOUBLE_EQ(p.lanes[0].inspection.false_reject_target, 0.01);
}

}  // namespace
}  // namespace rangex
