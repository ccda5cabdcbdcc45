// The whitened round kernels against their definition (pipeline/matched_kernels.h): learned
// from noise of known covariance, a kernel reaches the matched filter's signal-to-noise ratio
// sqrt(s' C^-1 s) computed from that covariance, and beats the Gaussian where the noise is
// correlated; in white noise it is the profile itself.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include "core/error.h"
#include "core/plant_config.h"
#include "pipeline/masked_smooth.h"
#include "pipeline/matched_kernels.h"

using namespace rangex;

namespace {

constexpr int kRows = 240, kCols = 240;

// White noise of spread `white` plus a field of spread `field` correlated by a Gaussian of
// `corr` px: its covariance at lag d is white^2 [d = 0] + field^2 exp(-|d|^2 / (4 corr^2)).
std::vector<float> noise(std::mt19937_64& rng, double white, double field, double corr) {
  std::normal_distribution<double> g;
  const size_t n = size_t(kRows) * kCols;
  std::vector<float> f(n), w(n);
  for (auto& x : f) x = float(g(rng));
  for (auto& x : w) x = float(g(rng));
  std::vector<uint8_t> all(n, 1);
  std::vector<float> s;
  masked_gaussian(f.data(), all.data(), kRows, kCols, corr, s);
  // A Gaussian of sigma shrinks unit white noise by 1 / (2 sqrt(pi) sigma).
  const double unit = 2 * std::sqrt(M_PI) * corr;
  std::vector<float> z(n);
  for (size_t i = 0; i < n; ++i) z[i] = float(white * w[i] + field * unit * s[i]);
  return z;
}

double true_cov(double white, double field, double corr, int dr, int dc) {
  return (dr == 0 && dc == 0 ? white * white : 0.0) +
         field * field * std::exp(-(dr * dr + dc * dc) / (4 * corr * corr));
}

// The spread of a kernel's output over the interior of independent noise images.
double output_spread(const std::vector<double>& taps, int radius, std::mt19937_64& rng,
                     double white, double field, double corr) {
  double s2 = 0;
  size_t k = 0;
  std::vector<uint8_t> all(size_t(kRows) * kCols, 1);
  std::vector<float> out;
  for (int rep = 0; rep < 4; ++rep) {
    const std::vector<float> z = noise(rng, white, field, corr);
    apply_kernel(z.data(), all.data(), kRows, kCols, taps, radius, out);
    for (int r = 20; r < kRows - 20; r += 3)
      for (int c = 20; c < kCols - 20; c += 3) {
        s2 += double(out[size_t(r) * kCols + c]) * out[size_t(r) * kCols + c];
        ++k;
      }
  }
  return std::sqrt(s2 / double(k));
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

// A kernel's output as the bone-like statistic at unit robust spread over the interior:
// its extreme away from the bones at `where` (into extremes) and its value at each (bones).
void bone_likeness(const std::vector<float>& out, const std::vector<std::pair<int, int>>& where,
                   int w, std::vector<double>& extremes, std::vector<double>& bones) {
  std::vector<float> sorted;
  for (int r = 20; r < kRows - 20; ++r)
    for (int cc = 20; cc < kCols - 20; ++cc) sorted.push_back(-out[size_t(r) * kCols + cc]);
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double med = sorted[sorted.size() / 2];
  for (auto& x : sorted) x = std::abs(x - float(med));
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double sd = sorted[sorted.size() / 2] / 0.6745;
  double top = 0;
  for (int r = 20; r < kRows - 20; ++r)
    for (int cc = 20; cc < kCols - 20; ++cc) {
      bool near = false;
      for (auto [r0, c0] : where) near = near || (std::abs(r - r0) <= w && std::abs(cc - c0) <= w);
      if (!near) top = std::max(top, (-out[size_t(r) * kCols + cc] - med) / sd);
    }
  extremes.push_back(top);
  for (auto [r0, c0] : where) bones.push_back((-out[size_t(r0) * kCols + c0] - med) / sd);
}

// Bone darkens z: a sphere's profile s (over a window of `radius`), 6 robust spreads deep at
// its centre, at each of `where`.
void plant_bones(std::vector<float>& z, const std::vector<std::pair<int, int>>& where,
                 const std::vector<double>& s, int radius) {
  const int w = 2 * radius + 1;
  for (auto [r0, c0] : where)
    for (int i = 0; i < w; ++i)
      for (int j = 0; j < w; ++j)
        z[size_t(r0 + i - radius) * kCols + size_t(c0 + j - radius)] -=
            float(6.0 * s[size_t(i) * w + j] / s[size_t(radius) * w + radius]);
}

// The covariance learned from 8 fields of that noise, to lags of 8 px.
TextureCovariance texture_of(std::mt19937_64& rng, double white, double field, double corr) {
  TextureCovariance c(8);
  std::vector<uint8_t> all(size_t(kRows) * kCols, 1);
  for (int f = 0; f < 8; ++f) {
    const std::vector<float> z = noise(rng, white, field, corr);
    c.add(z.data(), all.data(), kRows, kCols);
  }
  return c;
}

}  // namespace

TEST(MatchedKernels, InWhiteNoiseTheKernelIsTheProfile) {
  std::mt19937_64 rng(1);
  TextureCovariance c(8);
  std::vector<uint8_t> all(size_t(kRows) * kCols, 1);
  for (int f = 0; f < 4; ++f) {
    const std::vector<float> z = noise(rng, 1.0, 0.0, 1.0);
    c.add(z.data(), all.data(), kRows, kCols);
  }
  EXPECT_NEAR(c.at(0, 0), 1.0, 0.05);
  EXPECT_NEAR(c.at(0, 1), 0.0, 0.02);
  const std::vector<double> s = sphere_profile(2.0, 0.4, 0.4, 4, 0);
  const std::vector<double> h = whitened_kernel(c, s, 4);
  EXPECT_NEAR(dot(h, s), 1.0, 1e-9);  // scaled so
  const double cosine = dot(h, s) / std::sqrt(dot(h, h) * dot(s, s));
  EXPECT_GT(cosine, 0.99);
}

TEST(MatchedKernels, InCorrelatedNoiseTheKernelReachesTheMatchedFiltersSignalToNoise) {
  std::mt19937_64 rng(2);
  const double white = 0.6, field = 1.0, corr = 2.5;  // texture over ~2 mm at 0.4 mm pixels
  TextureCovariance c(8);
  std::vector<uint8_t> all(size_t(kRows) * kCols, 1);
  for (int f = 0; f < 8; ++f) {
    const std::vector<float> z = noise(rng, white, field, corr);
    c.add(z.data(), all.data(), kRows, kCols);
  }
  // The measured covariance is the field's (robust spread units: z has unit spread).
  const double v = true_cov(white, field, corr, 0, 0);
  EXPECT_NEAR(c.at(0, 2) / c.at(0, 0), true_cov(white, field, corr, 0, 2) / v, 0.03);
  EXPECT_NEAR(c.at(3, 3) / c.at(0, 0), true_cov(white, field, corr, 3, 3) / v, 0.03);

  const int radius = 4, w = 2 * radius + 1;
  const std::vector<double> s = sphere_profile(2.0, 0.4, 0.4, radius, 0);
  const std::vector<double> h = whitened_kernel(c, s, radius);
  // The optimum over the window from the true covariance: sqrt(s' C^-1 s) = s'h* / sqrt(h*'Ch*)
  // with h* the kernel of the true covariance.
  double quad = 0;
  for (size_t p = 0; p < h.size(); ++p)
    for (size_t q = 0; q < h.size(); ++q)
      quad += h[p] * h[q] *
              true_cov(white, field, corr, int(p / w) - int(q / w), int(p % w) - int(q % w));
  const double snr_learned_true = dot(h, s) / std::sqrt(quad);
  // And measured on noise it never saw.
  const double snr_learned = dot(h, s) / output_spread(h, radius, rng, white, field, corr);
  std::vector<double> g(h.size());
  for (int i = 0; i < w; ++i)
    for (int j = 0; j < w; ++j)
      g[size_t(i) * w + j] =
          std::exp(-0.5 * ((i - radius) * (i - radius) + (j - radius) * (j - radius)));
  const double snr_gauss = dot(g, s) / output_spread(g, radius, rng, white, field, corr);
  const double snr_profile = dot(s, s) / output_spread(s, radius, rng, white, field, corr);
  EXPECT_NEAR(snr_learned, snr_learned_true, 0.05 * snr_learned_true);
  // Its spread on the texture it was learned from, as the noise it never saw gives it (the
  // covariance is in units of the noise's own spread).
  EXPECT_NEAR(kernel_spread(c, h, radius) * std::sqrt(v),
              output_spread(h, radius, rng, white, field, corr),
              0.05 * output_spread(h, radius, rng, white, field, corr));
  EXPECT_GT(snr_learned, 1.3 * snr_gauss);
  EXPECT_GT(snr_learned, 1.3 * snr_profile);
}

TEST(MatchedKernels, ANeedlesProfileHoldsItsVolumeAlongItsAxis) {
  // A 3 mm needle of 0.6 mm on 0.4 mm pixels: its chords over the window sum to its volume
  // (pi r^2 L) over a pixel's area; across the belt it lies along the centre's rows, and
  // turned by 90 degrees it is the same needle transposed.
  const int radius = 5, w = 2 * radius + 1;
  const std::vector<double> across = needle_profile(3.0, 0.6, 0, 0.4, 0.4, radius, 0);
  const std::vector<double> along = needle_profile(3.0, 0.6, M_PI / 2, 0.4, 0.4, radius, 0);
  double sum = 0;
  for (double x : across) sum += x;
  EXPECT_NEAR(sum * 0.4 * 0.4, M_PI * 0.09 * 3.0, 0.02 * M_PI * 0.09 * 3.0);
  for (int i = 0; i < w; ++i)
    for (int j = 0; j < w; ++j) {
      EXPECT_NEAR(along[size_t(i) * w + j], across[size_t(j) * w + i], 1e-9) << i << "," << j;
      // 0.3 mm either side of its axis: into the rows beside the centre's (0.2 mm), no further
      if (std::abs(i - radius) > 1) EXPECT_EQ(across[size_t(i) * w + j], 0.0) << i << "," << j;
    }
  EXPECT_GT(across[size_t(radius) * w + radius], 0.3);  // its centre: 0.6 mm chords and less
  EXPECT_EQ(across[size_t(radius) * w], 0.0);           // beyond its end (1.5 mm)
}

TEST(MatchedKernels, InCorrelatedNoiseANeedleKernelBeatsTheElongatedGaussian) {
  // The needle statistic's kernels learned from texture correlated over ~2 mm: along its own
  // direction a 2 mm needle kernel reaches the matched filter's signal-to-noise on noise it
  // never saw, and beats the elongated Gaussian it replaces (3 x 0.7 px) by far more than the
  // round kernel beats the round Gaussian; a needle 90 degrees off its axis it barely sees.
  std::mt19937_64 rng(5);
  const double white = 0.6, field = 1.0, corr = 2.5;
  const TextureCovariance c = texture_of(rng, white, field, corr);
  MatchedKernels k;
  learn_needle_kernels(c, {2.0}, {0.6}, 0.4, 0.4, 0, k);
  ASSERT_EQ(k.needle_taps.size(), size_t(kNeedleDirections));
  EXPECT_EQ(k.needle_angles_deg[2], 45.0);
  EXPECT_EQ(k.needle_radii[0], 4);
  const int radius = 4, w = 2 * radius + 1;
  const std::vector<double>& h = k.needle_taps[0];  // across the belt
  const std::vector<double> s = needle_profile(2.0, 0.6, 0, 0.4, 0.4, radius, 0);
  const double v = true_cov(white, field, corr, 0, 0);
  const double spread = output_spread(h, radius, rng, white, field, corr);
  EXPECT_NEAR(k.needle_spreads[0] * std::sqrt(v), spread, 0.05 * spread);
  const double snr_learned = dot(h, s) / spread;
  double quad = 0;
  for (size_t p = 0; p < h.size(); ++p)
    for (size_t q = 0; q < h.size(); ++q)
      quad += h[p] * h[q] *
              true_cov(white, field, corr, int(p / w) - int(q / w), int(p % w) - int(q % w));
  EXPECT_NEAR(snr_learned, dot(h, s) / std::sqrt(quad), 0.05 * snr_learned);
  std::vector<double> g(h.size());
  for (int i = 0; i < w; ++i)
    for (int j = 0; j < w; ++j) {
      const double along = j - radius, across = i - radius;
      g[size_t(i) * w + j] = std::exp(-0.5 * (along * along / 9 + across * across / 0.49));
    }
  const double snr_gauss = dot(g, s) / output_spread(g, radius, rng, white, field, corr);
  EXPECT_GT(snr_learned, 2.0 * snr_gauss);
  const std::vector<double> crossing = needle_profile(2.0, 0.6, M_PI / 2, 0.4, 0.4, radius, 0);
  EXPECT_LT(dot(h, crossing) / spread, 0.5 * snr_learned);
}

TEST(MatchedKernels, ABankOfWidthsSeesAFlatFragmentBetterThanTheNarrowNeedle) {
  // A bone that lies flat (a 2 mm needle 1.0 mm wide) in texture correlated over ~2 mm: the
  // kernel learned for its width has more signal-to-noise on it than the 0.6 mm needle's
  // kernel along the same axis, and each width keeps its own kernels in the bank (they
  // travel with their diameters: LearnedKernelsTravelWithTheLearnedSettings...).
  std::mt19937_64 rng(7);
  const double white = 0.6, field = 1.0, corr = 2.5;
  const TextureCovariance c = texture_of(rng, white, field, corr);
  MatchedKernels k;
  learn_needle_kernels(c, {2.0}, {0.6, 1.0}, 0.4, 0.4, 0, k);
  ASSERT_EQ(k.needle_taps.size(), size_t(2 * kNeedleDirections));
  EXPECT_EQ(k.needle_diameters_mm.front(), 0.6);
  EXPECT_EQ(k.needle_diameters_mm.back(), 1.0);
  const int radius = 4;
  const std::vector<double> flat = needle_profile(2.0, 1.0, 0, 0.4, 0.4, radius, 0);
  auto snr = [&](size_t kernel) {
    const std::vector<double>& h = k.needle_taps[kernel];
    return dot(h, flat) / output_spread(h, radius, rng, white, field, corr);
  };
  const double narrow = snr(0), wide = snr(kNeedleDirections);  // both across the belt
  std::printf(
      "a 2 x 1.0 mm needle: signal-to-noise %.2f under the 0.6 mm kernel, %.2f under "
      "the 1.0 mm one\n",
      narrow, wide);
  EXPECT_GT(wide, 1.05 * narrow);
}

TEST(MatchedKernels, BrightSpecksAreClippedAndBoneLikeValuesKept) {
  std::vector<float> z(1000);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g;
  for (auto& x : z) x = float(g(rng));
  z[10] = 40, z[11] = -40;
  std::vector<uint8_t> use(z.size(), 1);
  use[12] = 0;
  std::vector<float> out;
  clip_bright(z.data(), use.data(), 1, int(z.size()), 3, 0, 0, out);
  EXPECT_LT(out[10], 3.5f);
  EXPECT_GT(out[10], 2.5f);
  EXPECT_EQ(out[11], -40.f);
  EXPECT_TRUE(std::isnan(out[12]));
  EXPECT_EQ(out[0], z[0]);
}

// Marbled meat: streaks of fat, brighter than lean (they attenuate less), over correlated
// texture. A whitened kernel's negative flank reads lean meat beside a streak as bone;
// clipping z at 1.5 robust spreads before the kernels (inspection.matched_clip), in learning
// and inspection alike, keeps that out, and bone, on the other side, keeps its signal. The
// weakest quarter of 2 mm bones against clean meat's typical bone-like extreme, clipped at
// 3 and at 1.5: where the streaks stand out (6 spreads, 7 % of the meat) 1.5 separates them
// 1.25x better; where they barely do (1.5 spreads, a fifth of the meat) it costs 5 %.
TEST(MatchedKernels, ClippingAtOneAndAHalfSpreadsSeparatesBoneFromMarbledMeat) {
  const size_t n = size_t(kRows) * kCols;
  std::vector<uint8_t> all(n, 1);
  double level = 0, bright = 0;  // the streaks: where a correlated field exceeds level
  auto marbled = [&](std::mt19937_64& rng) {
    std::vector<float> z = noise(rng, 0.6, 1.0, 2.5);
    const std::vector<float> streaks = noise(rng, 0.0, 1.0, 3.0);
    for (size_t i = 0; i < n; ++i)
      if (streaks[i] > level) z[i] += float(bright);
    return z;
  };
  const int radius = 4, w = 2 * radius + 1;
  const std::vector<double> s = sphere_profile(2.0, 0.4, 0.4, radius, 0);
  auto margin = [&](double clip) {
    std::mt19937_64 rng(11);
    TextureCovariance c(8, clip);
    for (int f = 0; f < 8; ++f) {
      const std::vector<float> z = marbled(rng);
      c.add(z.data(), all.data(), kRows, kCols);
    }
    const std::vector<double> h = whitened_kernel(c, s, radius);
    std::vector<double> extremes, bones;
    std::uniform_int_distribution<int> at(30, kRows - 30);
    for (int f = 0; f < 8; ++f) {
      std::vector<float> z = marbled(rng), zc, out;
      std::vector<std::pair<int, int>> where;
      for (int b = 0; b < 4; ++b) {
        const int r0 = at(rng), c0 = at(rng);
        where.push_back({r0, c0});
      }
      plant_bones(z, where, s, radius);
      clip_bright(z.data(), all.data(), kRows, kCols, clip, 0, 0, zc);
      apply_kernel(zc.data(), all.data(), kRows, kCols, h, radius, out);
      bone_likeness(out, where, w, extremes, bones);
    }
    std::sort(extremes.begin(), extremes.end());
    std::sort(bones.begin(), bones.end());
    // The weakest quarter of the bones against the clean meat's typical extreme.
    return bones[bones.size() / 4] / extremes[extremes.size() / 2];
  };
  level = 1.5, bright = 6;
  EXPECT_GT(margin(1.5), 1.15 * margin(3));
  level = 0.85, bright = 1.5;
  EXPECT_GT(margin(1.5), 0.9 * margin(3));
}

// Fat streaks along the muscle (ellipses 20-50 px long, 7-12 px wide, 6 spreads bright,
// about a tenth of the meat) over correlated texture, and 2 mm bones half inside streaks,
// half in lean meat. The clip alone cuts a bone in a streak to the streak's clipped value;
// with the bright enclosure (inspection.matched_enclosure) it keeps its depth below the
// streak, and the lean meat beside and between streaks, not enclosed, reads as before.
// The weakest quarter of each kind of bone against clean meat's typical extreme.
TEST(MatchedKernels, TheBrightEnclosureFindsBoneInsideAFatStreak) {
  const size_t n = size_t(kRows) * kCols;
  std::vector<uint8_t> all(n, 1);
  const int radius = 4, w = 2 * radius + 1;
  struct Streak {
    int r, c, half_len, half_wid;
  };
  auto marbled = [&](std::mt19937_64& rng, std::vector<Streak>& streaks) {
    std::vector<float> z = noise(rng, 0.6, 1.0, 2.5);
    std::uniform_int_distribution<int> pos(30, kRows - 30), len(10, 25), wid(4, 6);
    streaks.clear();
    for (int k = 0; k < 14; ++k) streaks.push_back({pos(rng), pos(rng), len(rng), wid(rng)});
    for (int r = 0; r < kRows; ++r)
      for (int c = 0; c < kCols; ++c)
        for (const Streak& s : streaks) {
          const double a = double(r - s.r) / s.half_len, b = double(c - s.c) / s.half_wid;
          if (a * a + b * b <= 1) {
            z[size_t(r) * kCols + c] += 6.f;
            break;
          }
        }
    return z;
  };
  const std::vector<double> s = sphere_profile(2.0, 0.4, 0.4, radius, 0);
  struct Margins {
    double in_fat, in_lean, clean;
  };
  auto margins = [&](int reach) {
    std::mt19937_64 rng(11);
    TextureCovariance c(8, 1.5, reach);
    std::vector<Streak> streaks;
    for (int f = 0; f < 8; ++f) {
      const std::vector<float> z = marbled(rng, streaks);
      c.add(z.data(), all.data(), kRows, kCols);
    }
    const std::vector<double> h = whitened_kernel(c, s, radius);
    std::vector<double> extremes, fat, lean;
    std::uniform_int_distribution<int> at(30, kRows - 30);
    for (int f = 0; f < 8; ++f) {
      std::vector<float> z = marbled(rng, streaks), zc, out;
      std::vector<std::pair<int, int>> where;
      for (int b = 0; b < 2; ++b) where.push_back({streaks[size_t(b)].r, streaks[size_t(b)].c});
      while (where.size() < 4) {  // lean meat: clear of every streak by a kernel's window
        const int r0 = at(rng), c0 = at(rng);
        bool clear = true;
        for (const Streak& st : streaks)
          clear = clear &&
                  (std::abs(r0 - st.r) > st.half_len + w || std::abs(c0 - st.c) > st.half_wid + w);
        if (clear) where.push_back({r0, c0});
      }
      plant_bones(z, where, s, radius);
      clip_bright(z.data(), all.data(), kRows, kCols, 1.5, reach, 0, zc);
      apply_kernel(zc.data(), all.data(), kRows, kCols, h, radius, out);
      std::vector<double> bones;
      bone_likeness(out, where, w, extremes, bones);
      fat.insert(fat.end(), bones.begin(), bones.begin() + 2);
      lean.insert(lean.end(), bones.begin() + 2, bones.end());
    }
    for (auto* v : {&extremes, &fat, &lean}) std::sort(v->begin(), v->end());
    const double typical = extremes[extremes.size() / 2];
    return Margins{fat[fat.size() / 4] / typical, lean[lean.size() / 4] / typical, typical};
  };
  const Margins clip = margins(0), enclosed = margins(radius);
  std::printf("bone in fat %.2f -> %.2f, in lean %.2f -> %.2f, clean extreme %.2f -> %.2f\n",
              clip.in_fat, enclosed.in_fat, clip.in_lean, enclosed.in_lean, clip.clean,
              enclosed.clean);
  EXPECT_LT(clip.in_fat, 1.0);
  EXPECT_GT(enclosed.in_fat, 1.0);
  EXPECT_GT(enclosed.in_lean, 0.9 * clip.in_lean);
}

// An air pocket removes meat: it stands far brighter than any texture. Clipped to the
// texture's bright level over its whole area, it is a plateau whose rim a whitened kernel's
// negative flank reads as bone (the nominal plant's rare false detections). Its level is
// learned as twice the fillets' median brightest thousandth; above it, a pocket and its ring
// are set to the median before the kernels, in learning and inspection alike. Pockets of
// 4-7 px radius, 25 spreads bright (two in a quarter of the learning fillets); 2 mm bones in lean
// meat: the rim's most bone-like value against clean meat's typical extreme falls from above 1.1 to
// under 1, and the bones keep their margin.
TEST(MatchedKernels, AnAirPocketsRimIsNotReadAsBone) {
  const size_t n = size_t(kRows) * kCols;
  std::vector<uint8_t> all(n, 1);
  const int radius = 4, w = 2 * radius + 1;
  struct Pocket {
    int r, c, rad;
  };
  auto fillet = [&](std::mt19937_64& rng, std::vector<Pocket>& pockets, bool with) {
    std::vector<float> z = noise(rng, 0.6, 1.0, 2.5);
    std::uniform_int_distribution<int> pos(40, kRows - 40), rad(4, 7);
    pockets.clear();
    if (with)
      for (int k = 0; k < 2; ++k) pockets.push_back({pos(rng), pos(rng), rad(rng)});
    for (const Pocket& p : pockets)
      for (int r = p.r - p.rad; r <= p.r + p.rad; ++r)
        for (int c = p.c - p.rad; c <= p.c + p.rad; ++c)
          if ((r - p.r) * (r - p.r) + (c - p.c) * (c - p.c) <= p.rad * p.rad)
            z[size_t(r) * kCols + c] += 25.f;
    return z;
  };
  // The level, learned from 16 fillets, a quarter of them with pockets.
  std::vector<double> bright;
  {
    std::mt19937_64 rng(5);
    std::vector<Pocket> p;
    for (int f = 0; f < 16; ++f) {
      const std::vector<float> z = fillet(rng, p, f % 4 == 0);
      bright.push_back(bright_quantile(z.data(), all.data(), n, 0.999));
    }
  }
  const double level = learned_void_level(bright, 2.0, 1.5);
  EXPECT_GT(level, 4.0);  // texture's brightest thousandth: about 3 spreads
  EXPECT_LT(level, 10.0);
  EXPECT_EQ(learned_void_level(bright, 0, 1.5), 0);
  EXPECT_EQ(learned_void_level({0.3, 0.4}, 2.0, 1.5), 1.5);  // never under the clip
  EXPECT_EQ(learned_void_level({}, 2.0, 1.5), 0);

  const std::vector<double> s = sphere_profile(2.0, 0.4, 0.4, radius, 0);
  struct Margins {
    double rim, bone;
  };
  auto margins = [&](double void_level) {
    std::mt19937_64 rng(11);
    TextureCovariance c(8, 1.5, radius, void_level);
    std::vector<Pocket> pockets;
    for (int f = 0; f < 8; ++f) {
      const std::vector<float> z = fillet(rng, pockets, f % 2 == 0);
      c.add(z.data(), all.data(), kRows, kCols);
    }
    const std::vector<double> h = whitened_kernel(c, s, radius);
    std::vector<double> extremes, bones, rims;
    std::uniform_int_distribution<int> at(30, kRows - 30);
    for (int f = 0; f < 8; ++f) {
      std::vector<float> z = fillet(rng, pockets, true), zc, out;
      std::vector<std::pair<int, int>> where;
      while (where.size() < 3) {  // bones in lean meat, clear of the pockets
        const int r0 = at(rng), c0 = at(rng);
        bool clear = true;
        for (const Pocket& p : pockets)
          clear =
              clear && (std::abs(r0 - p.r) > p.rad + 2 * w || std::abs(c0 - p.c) > p.rad + 2 * w);
        if (clear) where.push_back({r0, c0});
      }
      plant_bones(z, where, s, radius);
      clip_bright(z.data(), all.data(), kRows, kCols, 1.5, radius, void_level, zc);
      apply_kernel(zc.data(), all.data(), kRows, kCols, h, radius, out);
      // The pockets' surroundings count as bones here: their rims are measured apart.
      std::vector<std::pair<int, int>> away = where;
      for (const Pocket& p : pockets) away.push_back({p.r, p.c});
      std::vector<double> b, rim_here;
      bone_likeness(out, away, w + 4, extremes, b);
      bones.insert(bones.end(), b.begin(), b.begin() + long(where.size()));
      // The rim: outside each pocket, within a kernel's radius of its edge, bone-like values
      // in the same units (the clean meat's median and spread, from bone_likeness's pass).
      std::vector<float> v;
      for (int r = 20; r < kRows - 20; ++r)
        for (int cc = 20; cc < kCols - 20; ++cc) v.push_back(-out[size_t(r) * kCols + cc]);
      std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
      const double med = v[v.size() / 2];
      for (auto& x : v) x = std::abs(x - float(med));
      std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
      const double sd = v[v.size() / 2] / 0.6745;
      double top = 0;
      for (const Pocket& p : pockets)
        for (int r = p.r - p.rad - radius; r <= p.r + p.rad + radius; ++r)
          for (int cc = p.c - p.rad - radius; cc <= p.c + p.rad + radius; ++cc) {
            const int d2 = (r - p.r) * (r - p.r) + (cc - p.c) * (cc - p.c);
            if (d2 <= (p.rad + 1) * (p.rad + 1)) continue;
            top = std::max(top, (-out[size_t(r) * kCols + cc] - med) / sd);
          }
      rims.push_back(top);
    }
    for (auto* v : {&extremes, &bones, &rims}) std::sort(v->begin(), v->end());
    const double typical = extremes[extremes.size() / 2];
    return Margins{rims.back() / typical, bones[bones.size() / 4] / typical};
  };
  const Margins clipped = margins(0), flattened = margins(level);
  std::printf("void level %.2f; the pockets' rims %.2f -> %.2f, bone %.2f -> %.2f\n", level,
              clipped.rim, flattened.rim, clipped.bone, flattened.bone);
  EXPECT_GT(clipped.rim, 1.1);
  EXPECT_LT(flattened.rim, 1.0);
  EXPECT_GT(flattened.bone, 0.95 * clipped.bone);
  EXPECT_GT(flattened.bone, 1.0);
}

TEST(MatchedKernels, AKernelSeesFlatMeatOffTheFilletAndGivesNothingThere) {
  const int rows = 7, cols = 9, radius = 1;
  std::vector<float> z(size_t(rows) * cols);
  for (size_t i = 0; i < z.size(); ++i) z[i] = float(i % 5) - 2;
  std::vector<uint8_t> use(z.size(), 1);
  use[size_t(3) * cols + 5] = 0;
  z[size_t(3) * cols + 5] = 1000;  // off the fillet: not seen
  const std::vector<double> taps = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  std::vector<float> out;
  const double gain = apply_kernel(z.data(), use.data(), rows, cols, taps, radius, out);
  EXPECT_NEAR(gain, std::sqrt(285.0), 1e-12);
  EXPECT_TRUE(std::isnan(out[size_t(3) * cols + 5]));
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      if (!use[size_t(r) * cols + c]) continue;
      double ref = 0;
      for (int i = -1; i <= 1; ++i)
        for (int j = -1; j <= 1; ++j) {
          const int rr = r + i, cc = c + j;
          if (rr < 0 || rr >= rows || cc < 0 || cc >= cols || !use[size_t(rr) * cols + cc])
            continue;
          ref += taps[size_t(i + 1) * 3 + size_t(j + 1)] * z[size_t(rr) * cols + cc];
        }
      EXPECT_NEAR(out[size_t(r) * cols + c], ref, 1e-4) << r << "," << c;
      EXPECT_NEAR(apply_kernel_at(z.data(), use.data(), rows, cols, taps, radius, r, c), ref, 1e-9)
          << r << "," << c;
    }
}

// A fillet wider than the blocks apply_kernel sums at once (75 columns: two blocks and a
// part), a row with no usable pixel, a block with none, and holes: every usable pixel's sum
// is the direct sum over its window, every other pixel NaN.
TEST(MatchedKernels, BlockedSumsEqualTheDirectSumAcrossBlocksAndHoles) {
  const int rows = 23, cols = 75, radius = 4, w = 2 * radius + 1;
  std::mt19937 rng(5);
  std::normal_distribution<float> g;
  std::vector<float> z(size_t(rows) * cols);
  for (float& x : z) x = g(rng);
  std::vector<uint8_t> use(z.size(), 1);
  for (int c = 0; c < cols; ++c) use[size_t(6) * cols + c] = 0;  // a row off the fillet
  for (int r = 10; r < 14; ++r)
    for (int c = 32; c < 64; ++c) use[size_t(r) * cols + c] = 0;  // the second block of 4 rows
  for (size_t i = 0; i < z.size(); i += 13) use[i] = 0;           // holes
  z[size_t(2) * cols + 3] = std::numeric_limits<float>::quiet_NaN();
  std::vector<double> taps(size_t(w) * w);
  std::normal_distribution<double> h;
  for (double& t : taps) t = h(rng);
  std::vector<float> out;
  apply_kernel(z.data(), use.data(), rows, cols, taps, radius, out);
  ASSERT_EQ(out.size(), z.size());
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const size_t i = size_t(r) * cols + c;
      if (!use[i]) {
        EXPECT_TRUE(std::isnan(out[i])) << r << "," << c;
        continue;
      }
      double ref = 0, mag = 0;
      for (int a = -radius; a <= radius; ++a)
        for (int b = -radius; b <= radius; ++b) {
          const int rr = r + a, cc = c + b;
          if (rr < 0 || rr >= rows || cc < 0 || cc >= cols) continue;
          const size_t k = size_t(rr) * cols + cc;
          if (!use[k] || !std::isfinite(z[k])) continue;
          ref += taps[size_t(a + radius) * w + size_t(b + radius)] * z[k];
          mag += std::abs(taps[size_t(a + radius) * w + size_t(b + radius)] * z[k]);
        }
      EXPECT_NEAR(out[i], ref, 1e-6 * (1 + mag)) << r << "," << c;
    }
  // Padded once for a wider kernel (as inspection pads for its whole bank): the same sums,
  // bit for bit; a kernel wider than the padding is refused.
  const PaddedField wide = pad_field(z.data(), use.data(), rows, cols, radius + 3);
  std::vector<float> again;
  apply_kernel(wide, use.data(), taps, radius, again);
  ASSERT_EQ(again.size(), out.size());
  for (size_t i = 0; i < out.size(); ++i)
    if (std::isnan(out[i]))
      EXPECT_TRUE(std::isnan(again[i])) << i;
    else
      EXPECT_EQ(again[i], out[i]) << i;
  const std::vector<double> wider(size_t(2 * radius + 9) * size_t(2 * radius + 9), 1.0);
  EXPECT_THROW(apply_kernel(wide, use.data(), wider, radius + 4, again), Error);
}

TEST(MatchedKernels, LearnedKernelsTravelWithTheLearnedSettingsAndBadOnesAreRefused) {
  // A 5 mm sphere on 0.4 mm pixels needs a window of radius 7 (6.25 px to its rim); the
  // smaller ones keep the base window of radius 4, so the covariance is measured to lag 14.
  EXPECT_EQ(kernel_radius(1.5, 0.4, 0.4), 4);
  EXPECT_EQ(kernel_radius(3.0, 0.4, 0.4), 4);
  EXPECT_EQ(kernel_radius(3.3, 0.4, 0.4), 5);
  EXPECT_EQ(kernel_radius(5.0, 0.4, 0.4), 7);
  EXPECT_EQ(kernel_radius(5.0, 0.4, 0.2), 13);  // the finer of the two pitches decides
  TextureCovariance c(14);
  std::mt19937_64 rng(4);
  std::vector<uint8_t> all(size_t(kRows) * kCols, 1);
  const std::vector<float> z = noise(rng, 0.5, 1.0, 2.0);
  c.add(z.data(), all.data(), kRows, kCols);
  LearnedDetection L;
  L.band_edges_mm = {0, 10};
  for (auto& s : L.stats)
    s.thresholds = {6}, s.band_fraction = {1}, s.band_pixels = {5000}, s.band_thickness_mm = {6};
  L.matched = learn_matched_kernels(c, {1.5, 2.0, 5.0}, 0.4, 0.4, 0.5);
  ASSERT_EQ(L.matched.taps.size(), 3u);
  EXPECT_EQ(L.matched.radius(), 7);
  EXPECT_EQ(L.matched.radii, (std::vector<int>{4, 4, 7}));
  ASSERT_EQ(L.matched.taps[0].size(), 81u);
  ASSERT_EQ(L.matched.taps[2].size(), 225u);
  const LearnedDetection back = parse_learned_detection(learned_detection_yaml(L), "test");
  EXPECT_EQ(back.matched.radius(), 7);
  EXPECT_EQ(back.matched.radii, L.matched.radii);
  EXPECT_EQ(back.matched.sizes_mm, L.matched.sizes_mm);
  ASSERT_EQ(back.matched.spreads.size(), 3u);
  EXPECT_NEAR(back.matched.spreads[2], L.matched.spreads[2], 1e-9);
  for (size_t k = 0; k < 3; ++k) {
    ASSERT_EQ(back.matched.taps[k].size(), L.matched.taps[k].size());
    for (size_t i = 0; i < L.matched.taps[k].size(); ++i)
      EXPECT_NEAR(back.matched.taps[k][i], L.matched.taps[k][i],
                  1e-9 * std::abs(L.matched.taps[k][i]));
  }
  // The needle kernels travel beside them.
  learn_needle_kernels(c, {2.0}, {0.6}, 0.4, 0.4, 0.5, L.matched);
  ASSERT_EQ(L.matched.needle_taps.size(), size_t(kNeedleDirections));
  {
    const LearnedDetection n = parse_learned_detection(learned_detection_yaml(L), "test");
    EXPECT_EQ(n.matched.needle_diameters_mm, std::vector<double>(kNeedleDirections, 0.6));
    // One width writes one diameter, as every learning did before a bank of widths.
    EXPECT_NE(learned_detection_yaml(L).find("diameter_mm: 0.6"), std::string::npos);
    EXPECT_EQ(n.matched.needle_lengths_mm, L.matched.needle_lengths_mm);
    EXPECT_EQ(n.matched.needle_angles_deg, L.matched.needle_angles_deg);
    EXPECT_EQ(n.matched.needle_radii, L.matched.needle_radii);
    ASSERT_EQ(n.matched.needle_taps.size(), L.matched.needle_taps.size());
    for (size_t k = 0; k < n.matched.needle_taps.size(); ++k) {
      EXPECT_NEAR(n.matched.needle_spreads[k], L.matched.needle_spreads[k], 1e-9);
      for (size_t i = 0; i < L.matched.needle_taps[k].size(); ++i)
        EXPECT_NEAR(n.matched.needle_taps[k][i], L.matched.needle_taps[k][i],
                    1e-9 * std::abs(L.matched.needle_taps[k][i]));
    }
    const std::string with = learned_detection_yaml(L);
    std::string bad = with;  // a direction outside [0, 180)
    bad.replace(bad.find("angles_deg: [0, "), 16, "angles_deg: [180, ");
    EXPECT_THROW(parse_learned_detection(bad, "test"), Error);
    bad = with;  // one kernel's taps missing
    const size_t last = bad.rfind("\n      - [");
    bad.erase(last, bad.find('\n', last + 1) - last);
    EXPECT_THROW(parse_learned_detection(bad, "test"), Error);
  }
  // A bank of two widths travels with one diameter per kernel; one too few, or both keys,
  // is refused.
  L.matched.drop_needles();
  learn_needle_kernels(c, {2.0}, {0.6, 1.0}, 0.4, 0.4, 0.5, L.matched);
  {
    const std::string two = learned_detection_yaml(L);
    const LearnedDetection n = parse_learned_detection(two, "test");
    EXPECT_EQ(n.matched.needle_diameters_mm, L.matched.needle_diameters_mm);
    ASSERT_EQ(n.matched.needle_taps.size(), size_t(2 * kNeedleDirections));
    EXPECT_NEAR(n.matched.needle_taps.back()[40], L.matched.needle_taps.back()[40], 1e-9);
    std::string bad = two;
    bad.replace(bad.find("diameters_mm: [0.6, "), 20, "diameters_mm: [");
    EXPECT_THROW(parse_learned_detection(bad, "test"), Error);
    bad = two;
    bad.replace(bad.find("diameters_mm: "), 14, "diameter_mm: 0.6\n    diameters_mm: ");
    EXPECT_THROW(parse_learned_detection(bad, "test"), Error);
  }
  L.matched.drop_needles();
  const std::string yaml = learned_detection_yaml(L);
  EXPECT_EQ(yaml.find("needles"), std::string::npos);
  {
    std::string bad = yaml;  // taps for radius 4 under a window of 5
    bad.replace(bad.find("radii: [4, 4, 7]"), 16, "radii: [5, 4, 7]");
    EXPECT_THROW(parse_learned_detection(bad, "test"), Error);
  }
  {
    std::string bad = yaml;  // a window beyond the bank's radius
    bad.replace(bad.find("radii: [4, 4, 7]"), 16, "radii: [4, 4, 8]");
    EXPECT_THROW(parse_learned_detection(bad, "test"), Error);
  }
  {
    // A file written before windows differed (no radii): one window, radius, for all.
    LearnedDetection one = L;
    one.matched = learn_matched_kernels(c, {1.5, 2.0}, 0.4, 0.4, 0.5);
    std::string old = learned_detection_yaml(one);
    old.erase(old.find("\n  radii: [4, 4]"), 16);
    ASSERT_EQ(old.find("radii"), std::string::npos);
    const LearnedDetection read = parse_learned_detection(old, "test");
    EXPECT_EQ(read.matched.radii, (std::vector<int>{4, 4}));
    std::string bad = old;  // taps for radius 4 under a window of 3
    bad.replace(bad.find("radius: 4"), 9, "radius: 3");
    EXPECT_THROW(parse_learned_detection(bad, "test"), Error);
  }
  {
    // The bright enclosure's reach and the void level travel with the kernels learned with
    // them; a file without them is the clip alone, and a reach beyond 16 px or a void level
    // under the clip is refused, naming it.
    EXPECT_EQ(L.matched.enclosure_px, 0);
    EXPECT_EQ(yaml.find("enclosure_px"), std::string::npos);
    EXPECT_EQ(yaml.find("void_level"), std::string::npos);
    EXPECT_EQ(parse_learned_detection(yaml, "test").matched.void_level, 0);
    TextureCovariance enclosed(14, 1.5, 4, 6.5);
    enclosed.add(z.data(), all.data(), kRows, kCols);
    LearnedDetection e = L;
    e.matched = learn_matched_kernels(enclosed, {1.5, 2.0}, 0.4, 0.4, 0.5);
    EXPECT_EQ(e.matched.enclosure_px, 4);
    EXPECT_EQ(e.matched.void_level, 6.5);
    const std::string with = learned_detection_yaml(e);
    EXPECT_EQ(parse_learned_detection(with, "test").matched.enclosure_px, 4);
    EXPECT_EQ(parse_learned_detection(with, "test").matched.void_level, 6.5);
    for (auto [was, bad, key] :
         {std::array<const char*, 3>{"enclosure_px: 4", "enclosure_px: 17", "enclosure_px"},
          {"void_level: 6.5", "void_level: 1.2", "void_level"}}) {
      std::string y = with;
      y.replace(y.find(was), std::string(was).size(), bad);
      try {
        parse_learned_detection(y, "test");
        FAIL() << bad;
      } catch (const Error& x) {
        EXPECT_NE(std::string(x.what()).find(key), std::string::npos) << x.what();
      }
    }
    EXPECT_THROW(TextureCovariance(8, 1.5, -1), Error);
    EXPECT_THROW(TextureCovariance(8, 1.5, 0, -1), Error);
  }
  // A sphere too large for the lags measured is refused, naming it.
  TextureCovariance short_lags(8);
  short_lags.add(z.data(), all.data(), kRows, kCols);
  try {
    learn_matched_kernels(short_lags, {5.0}, 0.4, 0.4, 0);
    FAIL() << "a 5 mm sphere with lags measured to 8 px";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("5 mm sphere"), std::string::npos) << e.what();
  }
}
