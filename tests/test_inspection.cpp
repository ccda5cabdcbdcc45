// Compensation, detection and the fail-safe decisions on synthetic fillets with known truth.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>

#include "core/lane_config.h"
#include "pipeline/inspection.h"
#include "pipeline/matched_kernels.h"
#include "pipeline/wall_gaps.h"
#include "sim/synthetic_fillet.h"

using namespace rangex;

namespace {

using Bone = sim::PlantedBone;
using sim::synthetic_fillet;

InspectionParams params() {
  return default_lane_config(0).inspection;
}

// A whitened kernel for a sphere of d_mm learned from white noise (where it is the sphere's
// profile), the texture clipped at `clip` spreads with the bright enclosure of `reach` px.
MatchedKernels white_noise_kernels(double d_mm, double clip, int reach, uint64_t seed) {
  TextureCovariance white(8, clip, reach);
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g;
  const int side = 120;
  std::vector<float> z(size_t(side) * side);
  std::vector<uint8_t> all(z.size(), 1);
  for (int k = 0; k < 4; ++k) {
    for (float& x : z) x = g(rng);
    white.add(z.data(), all.data(), side, side);
  }
  return learn_matched_kernels(white, {d_mm}, 0.4, 0.4, 0);
}

}  // namespace

TEST(Inspection, PseudoXrayRecoversKnownBeta) {
  const double b0 = std::log(3600.0), b1 = -0.031;
  const FilletImage f = synthetic_fillet(b0, b1, {}, 1);
  const FilletResult r = inspect_fillet(f, params(), true);
  ASSERT_TRUE(r.fitted);
  EXPECT_TRUE(r.fit.converged);
  EXPECT_NEAR(r.fit.beta0, b0, 2e-3);
  EXPECT_NEAR(r.fit.beta1, b1, 1e-4);
  // A straight beam: the parabola's bend is nothing (1e-5 per mm^2 bends 40 mm by 0.016).
  EXPECT_LT(std::abs(r.fit.beta2), 1e-5);
  // P = exp(b0 + b1 T + b2 T^2) pixel by pixel.
  for (size_t i = 0; i < f.size(); i += 97)
    if (f.mask[i]) {
      const double t = f.thickness[i];
      EXPECT_NEAR(r.pseudo[i], std::exp(r.fit.beta0 + t * (r.fit.beta1 + r.fit.beta2 * t)),
                  1e-2 * r.pseudo[i]);
    }
  // Noise model: photon noise a = 1 / (photons per DN), electronic b = 2^2.
  EXPECT_NEAR(r.noise.a, 0.1, 0.03);
  EXPECT_EQ(r.decision, Decision::kPass) << r.reason;
  EXPECT_TRUE(r.fragments.empty());
  EXPECT_NEAR(r.resid_mean_dn, 0, 2);
}

// A polychromatic beam bends ln I (the dissertation's straight line does not hold): the parabola
// follows the bend and finds the bones, where the line leaves a thickness-shaped residual that
// hides them.
TEST(Inspection, HardenedBeamIsFollowedByTheParabola) {
  const std::vector<Bone> bones = {{-20, 130, 1.5, 0.06}, {5, 160, 2.0, 0.05}, {0, 190, 1.5, 0.06}};
  const FilletImage f = synthetic_fillet(std::log(3600.0), -0.03, bones, 4, 300, 200, 0.3);
  InspectionParams line = params(), parabola = params();
  line.attenuation_degree = 1;
  parabola.attenuation_degree = 2;
  const FilletResult a = inspect_fillet(f, line, false), b = inspect_fillet(f, parabola, false);
  ASSERT_TRUE(a.fitted && b.fitted) << a.reason << b.reason;
  EXPECT_GT(b.fit.beta2, 0);  // the bend is upward: thick meat attenuates less per mm
  EXPECT_LT(b.fit.scale, 0.8 * a.fit.scale);
  ASSERT_EQ(b.decision, Decision::kReject) << b.reason;
  ASSERT_EQ(b.fragments.size(), bones.size());
  for (const Bone& bone : bones) {
    double best = 1e9;
    for (const Blob& d : b.fragments)
      best = std::min(best, std::hypot(d.x_mm - bone.x_mm, d.y_mm - bone.y_mm));
    EXPECT_LE(best, 1.0) << "bone at " << bone.x_mm << ", " << bone.y_mm;
  }
  std::printf("hardened beam: line scale %.4f, %zu fragments; parabola scale %.4f, %zu fragments\n",
              a.fit.scale, a.fragments.size(), b.fit.scale, b.fragments.size());
}

// Cartilage: wide and a little denser than meat; bone: small and dense. meat_mm tells them
// apart (in mm of the fillet's meat: 0.02 / 0.03 is 0.7 mm, 0.12 / 0.03 is 4 mm at the peak).
TEST(Inspection, ContrastInMillimetresOfMeatDropsCartilageOnlyWhenAsked) {
  const std::vector<Bone> planted = {{-15, 140, 6.0, 0.02}, {10, 180, 1.5, 0.12}};
  const FilletImage f = synthetic_fillet(std::log(3600.0), -0.03, planted, 5);
  InspectionParams p = params();
  const FilletResult all = inspect_fillet(f, p, false);
  ASSERT_EQ(all.fragments.size(), 2u) << all.reason;
  for (const Blob& b : all.fragments) {
    const bool cartilage = std::hypot(b.x_mm + 15, b.y_mm - 140) < 3;
    std::printf("%s: %.2f mm of meat\n", cartilage ? "cartilage" : "bone", b.meat_mm);
    // The peak of a 3x3 mean: a little below the centre on the bone's dome, a little above
    // on the flat cartilage (the largest of its noisy means).
    EXPECT_NEAR(b.meat_mm, cartilage ? 0.75 : 3.8, cartilage ? 0.2 : 0.3) << b.x_mm;
  }
  p.min_fragment_meat_mm = 1.5;
  const FilletResult strong = inspect_fillet(f, p, false);
  ASSERT_EQ(strong.fragments.size(), 1u);
  EXPECT_NEAR(strong.fragments[0].x_mm, 10, 1.0);
  EXPECT_EQ(strong.decision, Decision::kReject);
}

namespace {

// The highest round extreme of a result over its bands (-inf without one).
double round_extreme(const FilletResult& r) {
  double x = -INFINITY;
  for (const BandExtreme& e : r.extremes)
    if (e.stat == kStatRound) x = std::max(x, e.x);
  return x;
}

}  // namespace

// Under learned thresholds, what the plant's floor drops is no reject, and the extremes that
// drift follows leave it out: cartilage the floor keeps out of the decisions does not read as
// a rougher product. Without learned thresholds (what learning fits) they keep it.
TEST(Inspection, ExtremesUnderLearnedThresholdsLeaveOutWhatTheFloorDrops) {
  const FilletImage f = synthetic_fillet(std::log(3600.0), -0.03, {{-15, 140, 6.0, 0.02}}, 5);
  InspectionParams p = params();
  LearnedDetection& L = p.learned;
  L.band_edges_mm = {0, 1000};  // one band, each threshold the fixed one
  for (int s = 0; s < kStatistics; ++s)
    L.stats[size_t(s)].thresholds = {s == kStatAir ? p.air_z_threshold : p.z_threshold};
  const FilletResult all = inspect_fillet(f, p, false);
  ASSERT_EQ(all.fragments.size(), 1u) << all.reason;  // the cartilage, under 1.5 mm of meat
  ASSERT_LT(all.fragments[0].meat_mm, 1.5);
  EXPECT_GT(round_extreme(all), p.z_threshold);

  p.min_fragment_meat_mm = 1.5;
  const FilletResult floored = inspect_fillet(f, p, false);
  EXPECT_TRUE(floored.fragments.empty());
  EXPECT_EQ(floored.decision, Decision::kPass);
  ASSERT_EQ(floored.extremes.size(), all.extremes.size());
  EXPECT_LE(round_extreme(floored), p.z_threshold);  // the meat around it, below the threshold
  for (size_t k = 0; k < all.extremes.size(); ++k)
    if (all.extremes[k].stat == kStatAir) {
      EXPECT_EQ(floored.extremes[k].x, all.extremes[k].x);  // air is not the floor's
    }
  std::printf("round extreme %.2f with the cartilage, %.2f with the floor dropping it\n",
              round_extreme(all), round_extreme(floored));

  // Without learned thresholds (a learning run's inspection) the extremes keep it.
  p.learned = {};
  const FilletResult learning = inspect_fillet(f, p, false);
  EXPECT_TRUE(learning.fragments.empty());
  EXPECT_GT(round_extreme(learning), p.z_threshold);
}

namespace {

// A fold's step of 6 mm (to nothing at the fillet's edge) from row foot(c) on, in column c,
// and the bone of the synthetic fillet beyond it at (10, 200).
FilletImage folded(uint64_t seed, const std::function<int(int)>& foot) {
  const double b1 = -0.03;
  FilletImage f = synthetic_fillet(std::log(3600.0), b1, {{10, 200, 1.5, 0.12}}, seed);
  for (int c = 0; c < f.cols; ++c)
    for (int r = foot(c); r < f.rows; ++r) {
      const size_t i = size_t(r) * f.cols + c;
      const double step = 6 * std::min(1.0, f.thickness[i] / 12.0);
      f.thickness[i] += float(step);
      f.xray[i] = uint16_t(std::lround(f.xray[i] * std::exp(b1 * step)));
    }
  return f;
}

// How many of res's fragments `on` holds.
int count(const FilletResult& res, const std::function<bool(const Blob&)>& on) {
  int n = 0;
  for (const Blob& b : res.fragments) n += on(b);
  return n;
}

// f's gaps closed as the lane's assembly does, inspected with the closures' spread and
// without it (as before it was carried): the detections on the step (on_step) in each, and
// the bone beyond it found in both, alone.
void step_is_not_bone(FilletImage f, const std::function<bool(const Blob&)>& on_step,
                      const char* what) {
  EXPECT_GT(close_wall_gaps(f, 4, 1.5), 0);
  ASSERT_EQ(f.closure_step_mm.size(), f.size());
  FilletImage unknown = f;
  unknown.closure_step_mm.clear();
  auto bone = [](const Blob& b) { return std::hypot(b.x_mm - 10, b.y_mm - 200) < 1.0; };
  const FilletResult without = inspect_fillet(unknown, params(), false);
  const FilletResult with = inspect_fillet(f, params(), false);
  ASSERT_TRUE(without.fitted && with.fitted) << without.reason << with.reason;
  EXPECT_GT(count(without, on_step), 0);  // what the closure did before
  EXPECT_EQ(count(with, on_step), 0);
  EXPECT_EQ(count(without, bone), 1);
  EXPECT_EQ(count(with, bone), 1);
  EXPECT_EQ(with.fragments.size(), 1u);
  std::printf("%s: %d fragments on it without the closure's spread, %d with\n", what,
              count(without, on_step), count(with, on_step));
}

}  // namespace

// A fold's step across the fillet, and the camera frame of the row on it lost: the closure
// takes the row below the step (a wall's foot), the detector saw the meat above it, 6 mm more
// of it, as bone looks. The closure's spread says the thickness there is not known; a bone
// beyond the step is still found.
TEST(Inspection, ALostLineOnAFoldsStepIsNotTakenForBone) {
  const int R = 150;
  FilletImage f = folded(7, [&](int) { return R; });
  for (int c = 0; c < f.cols; ++c) f.thickness[size_t(R) * f.cols + c] = NAN;
  const double row_y = f.y0_mm + 0.4 * R;
  step_is_not_bone(
      f, [&](const Blob& b) { return std::abs(b.y_mm - row_y) < 2; }, "lost row on a 6 mm step");
}

// A fold's oblique step whose foot the cameras could not see: in each column a gap of three
// rows where the meat already stands 6 mm higher, closed as a wall in the gap's middle, so two
// of its rows take the low side, one error along the whole step. With the pixels' own
// variance alone it was still a detection (smoothed z -7 against -49); the kernels' share of
// it (closure_spread.h) leaves none.
TEST(Inspection, AFoldsObliqueStepHiddenFromTheCamerasIsNotTakenForBone) {
  auto foot = [](int c) { return 140 + c / 4; };  // the step's row in column c
  FilletImage f = folded(8, foot);
  for (int c = 0; c < f.cols; ++c)
    for (int r = foot(c); r < foot(c) + 3; ++r)
      if (f.mask[size_t(r) * f.cols + c]) f.thickness[size_t(r) * f.cols + c] = NAN;
  step_is_not_bone(
      f,
      [&](const Blob& b) {
        const int c = int(std::lround((b.x_mm - f.x0_mm) / f.pitch_mm));
        return std::abs((b.y_mm - f.y0_mm) / 0.4 - foot(std::clamp(c, 0, f.cols - 1))) < 6;
      },
      "hidden oblique 6 mm step");
}

// A fold's flap standing 5 mm high at the fillet's outline (rows 120-180, right of the
// middle): the outline is a cliff. Along 7 rows the measured rim pixel is 3 mm short (the
// laser's samples either side of the wall, interpolated across it; folds_lost_lines' clean
// rejects, docs/inspection.md): the X-ray saw the meat the thickness missed, as bone looks.
// The rim's wall, carried like a closure's (rim_walls), leaves no detection there; a bone
// 2 mm inside that rim, and the fillet's bone, are found with it as without.
TEST(Inspection, AFlapsWallAtTheOutlineMeasuredShortIsNotTakenForBone) {
  const double b1 = -0.03;
  FilletImage f = synthetic_fillet(std::log(3600.0), b1, {{10, 200, 1.5, 0.12}}, 9);
  auto rim_col = [&](int r) {
    int e = -1;
    for (int c = f.cols / 2; c < f.cols; ++c)
      if (f.mask[size_t(r) * f.cols + c]) e = c;
    return e;
  };
  for (int r = 120; r < 180; ++r)
    for (int c = f.cols / 2; c < f.cols; ++c) {
      const size_t i = size_t(r) * f.cols + c;
      if (!f.mask[i]) continue;
      f.thickness[i] += 5;
      f.xray[i] = uint16_t(std::lround(f.xray[i] * std::exp(b1 * 5)));
    }
  const int short0 = 140, short1 = 147;
  for (int r = short0; r < short1; ++r) f.thickness[size_t(r) * f.cols + rim_col(r)] -= 3;
  // A bone 2 mm (5 px) inside the flap's rim, further along it.
  const int bone_row = 165, bone_col = rim_col(bone_row) - 5;
  const double bx = f.x0_mm + 0.4 * bone_col, by = f.y0_mm + 0.4 * bone_row;
  // Its attenuation, 0.12 at the centre of a 1 mm radius, onto the flap's X-ray.
  for (int r = bone_row - 4; r <= bone_row + 4; ++r)
    for (int c = bone_col - 4; c <= bone_col + 4; ++c) {
      const double d2 = (std::pow(r - bone_row, 2) + std::pow(c - bone_col, 2)) * 0.16;
      const size_t i = size_t(r) * f.cols + c;
      if (d2 < 1)
        f.xray[i] = uint16_t(std::lround(f.xray[i] * std::exp(-0.12 * std::sqrt(1 - d2))));
    }
  auto on_rim = [&](const Blob& b) {
    const double r = (b.y_mm - f.y0_mm) / 0.4;
    return r > short0 - 4 && r < short1 + 4 && b.x_mm > 0;
  };
  auto near_rim = [&](const Blob& b) { return std::hypot(b.x_mm - bx, b.y_mm - by) < 1.0; };
  auto fillets = [&](const Blob& b) { return std::hypot(b.x_mm - 10, b.y_mm - 200) < 1.0; };
  InspectionParams without = params(), with = params();
  without.rim_walls = false;
  with.rim_walls = true;
  const FilletResult a = inspect_fillet(f, without, false), b = inspect_fillet(f, with, false);
  ASSERT_TRUE(a.fitted && b.fitted) << a.reason << b.reason;
  std::printf(
      "a flap's rim 3 mm short along 7 rows: %d fragments on it without rim_walls, %d with\n",
      count(a, on_rim), count(b, on_rim));
  EXPECT_GT(count(a, on_rim), 0);  // what the rim did before
  EXPECT_EQ(count(b, on_rim), 0);
  EXPECT_EQ(count(a, near_rim), 1);
  EXPECT_EQ(count(b, near_rim), 1);
  EXPECT_EQ(count(a, fillets), 1);
  EXPECT_EQ(count(b, fillets), 1);
  EXPECT_EQ(b.fragments.size(), 2u);
}

// A small bone found by a whitened kernel (learned here from white noise, where the kernel is
// its sphere's profile): its contrast is read under that kernel, the excess through its
// centre, where the Gaussians smooth it down to part of that. A plant's min_fragment_meat_mm
// between the two keeps it.
TEST(Inspection, ABonesContrastIsReadUnderTheWhitenedKernelThatFoundIt) {
  // A 1.5 mm sphere whose centre attenuates like 4 mm of this meat (0.12 / 0.03).
  const std::vector<Bone> bone = {{5, 160, 0.75, 0.12}};
  const FilletImage f = synthetic_fillet(std::log(3600.0), -0.03, bone, 6);
  InspectionParams p = params();
  const FilletResult gauss = inspect_fillet(f, p, false);
  ASSERT_EQ(gauss.fragments.size(), 1u) << gauss.reason;
  p.learned.matched = white_noise_kernels(1.5, 3, 0, 5);
  const FilletResult kern = inspect_fillet(f, p, false);
  ASSERT_EQ(kern.fragments.size(), 1u) << kern.reason;
  std::printf("meat_mm: Gaussians %.2f, whitened kernel %.2f (truth 4.0)\n",
              gauss.fragments[0].meat_mm, kern.fragments[0].meat_mm);
  EXPECT_NEAR(kern.fragments[0].meat_mm, 4.0, 0.6);
  EXPECT_LT(gauss.fragments[0].meat_mm, 3.0);
  p.min_fragment_meat_mm = 3.0;
  EXPECT_EQ(inspect_fillet(f, p, false).fragments.size(), 1u);
  p.learned.matched = {};
  EXPECT_TRUE(inspect_fillet(f, p, false).fragments.empty());
}

namespace {

// A lean island inside a ring of fat, centred on pixel (r0, c0): the ring 3-6 px from the
// centre attenuates `ring` less than the fillet's prediction (-ln(I / P) = -ring), the island
// `island` (negative: less), and a bone of `bone` at its centre pixel and its four neighbours.
constexpr int kRingRow = 150, kRingCol = 113;  // x 5.2 mm, y 160 mm
FilletImage fat_ring(FilletImage f, double ring, double island, double bone) {
  const int r0 = kRingRow, c0 = kRingCol;
  for (int r = r0 - 6; r <= r0 + 6; ++r)
    for (int c = c0 - 6; c <= c0 + 6; ++c) {
      const double d = std::hypot(r - r0, c - c0);
      double excess = d <= 6 && d >= 3 ? -ring : d < 3 ? island : 0;
      if (std::abs(r - r0) + std::abs(c - c0) <= 1) excess += bone;
      uint16_t& x = f.xray[size_t(r) * f.cols + c];
      x = uint16_t(std::lround(x * std::exp(-excess)));
    }
  return f;
}

}  // namespace

// Whitened kernels read a pixel enclosed by bright fat by its depth below the fat
// (matched_enclosure), so that a bone in a fat streak keeps its contrast. A lean island in a
// ring of fat reads the same way, yet adds no attenuation over its pixels. Where the plant
// asks for it (require_added_attenuation), that is no fragment and no reject; a bone in the
// island that adds attenuation stays one, a weak one that does not is dropped too (the
// choice's cost).
TEST(Inspection, WhereAskedADetectionThatAddsNoAttenuationIsNoFragment) {
  const FilletImage clean = synthetic_fillet(std::log(3600.0), -0.03, {}, 7);
  InspectionParams p = params();
  p.learned.matched = white_noise_kernels(2.0, 0.5, 4, 9);
  ASSERT_GT(p.learned.matched.enclosure_px, 0);
  const InspectionParams off = p;
  EXPECT_FALSE(off.require_added_attenuation);  // the default: the plant's choice
  p.require_added_attenuation = true;
  const FilletImage island = fat_ring(clean, 0.15, -0.01, 0);
  const FilletResult seen = inspect_fillet(island, off, true);
  ASSERT_EQ(seen.fragments.size(), 1u) << seen.reason;
  const Blob& b = seen.fragments[0];
  EXPECT_NEAR(b.x_mm, 5.2, 1.0);
  EXPECT_NEAR(b.y_mm, 160, 1.0);
  // The ring and island in its box add none either (the residual the inspection kept).
  double sum = 0;
  const double px_area = island.pitch_mm * island.step_mm;
  for (int r = b.row0; r <= b.row1; ++r)
    for (int c = b.col0; c <= b.col1; ++c) {
      const size_t i = size_t(r) * island.cols + c;
      if (std::hypot(r - kRingRow, c - kRingCol) <= 6.5 && std::isfinite(seen.residual[i]))
        sum += -seen.residual[i] * px_area;
    }
  std::printf("the island: peak z %.1f, %.2f mm^2, adds %.4f mm^2 (its box %.4f)\n", b.peak_z,
              b.area_mm2, b.attenuation_mm2, sum);
  EXPECT_LE(b.attenuation_mm2, 0);
  EXPECT_LT(sum, 0);
  const FilletResult dropped = inspect_fillet(island, p, false);
  EXPECT_TRUE(dropped.fragments.empty()) << dropped.reason;
  EXPECT_EQ(dropped.decision, Decision::kPass);
  // What learning fits and drift follows is the statistic, the same with the rule or without.
  ASSERT_EQ(dropped.extremes.size(), seen.extremes.size());
  for (size_t k = 0; k < seen.extremes.size(); ++k)
    EXPECT_EQ(dropped.extremes[k].x, seen.extremes[k].x);

  const FilletResult bone = inspect_fillet(fat_ring(clean, 0.15, -0.01, 0.15), p, false);
  ASSERT_EQ(bone.fragments.size(), 1u) << bone.reason;
  EXPECT_GT(bone.fragments[0].attenuation_mm2, 0);
  EXPECT_EQ(bone.decision, Decision::kReject);
  const FilletImage weak = fat_ring(clean, 0.15, -0.01, 0.03);
  const FilletResult weak_seen = inspect_fillet(weak, off, false);
  ASSERT_EQ(weak_seen.fragments.size(), 1u) << weak_seen.reason;
  EXPECT_LE(weak_seen.fragments[0].attenuation_mm2, 0);
  EXPECT_TRUE(inspect_fillet(weak, p, false).fragments.empty());
}

namespace {

// f with every third pixel of the first quarter of its rows (y 100-130 mm) without thickness:
// about 8 % of the meat, beyond max_invalid_fraction.
FilletImage holes(FilletImage f) {
  int n = 0;
  for (int r = 0; r < f.rows / 4; ++r)
    for (int c = 0; c < f.cols; c += 3) {
      const size_t i = size_t(r) * f.cols + c;
      if (f.mask[i] && std::isfinite(f.thickness[i])) f.thickness[i] = NAN, ++n;
    }
  f.invalid_thickness_px = n;
  return f;
}

// Every field of a decision that the thresholds can change, equal (timings aside).
void expect_same_decision(const FilletResult& a, const FilletResult& b, const char* what) {
  SCOPED_TRACE(what);
  EXPECT_EQ(a.decision, b.decision);
  EXPECT_EQ(a.reason, b.reason);
  EXPECT_EQ(a.fitted, b.fitted);
  EXPECT_EQ(a.z_spread, b.z_spread);
  ASSERT_EQ(a.fragments.size(), b.fragments.size());
  for (size_t k = 0; k < a.fragments.size(); ++k) {
    const Blob &x = a.fragments[k], &y = b.fragments[k];
    EXPECT_EQ(x.x_mm, y.x_mm);
    EXPECT_EQ(x.y_mm, y.y_mm);
    EXPECT_EQ(x.peak_z, y.peak_z);
    EXPECT_EQ(x.meat_mm, y.meat_mm);
    EXPECT_EQ(x.attenuation_mm2, y.attenuation_mm2);
    EXPECT_EQ(x.pixels, y.pixels);
  }
  EXPECT_EQ(a.air_pockets.size(), b.air_pockets.size());
  ASSERT_EQ(a.extremes.size(), b.extremes.size());
  for (size_t k = 0; k < a.extremes.size(); ++k) {
    EXPECT_EQ(a.extremes[k].stat, b.extremes[k].stat);
    EXPECT_EQ(a.extremes[k].band, b.extremes[k].band);
    EXPECT_EQ(a.extremes[k].x, b.extremes[k].x);
    EXPECT_EQ(a.extremes[k].n, b.extremes[k].n);
  }
}

}  // namespace

// Learning's trade-off decides each injected fillet under several targets' thresholds on one
// model and one set of statistics: each decision must be the one its own inspection makes.
TEST(Inspection, EachSetOfThresholdsDecidesAsItsOwnInspectionWould) {
  // Bones from clear to faint, so that thresholds of 4, 7 and 12 find different ones.
  const std::vector<Bone> bones = {
      {-20, 130, 1.5, 0.15}, {5, 160, 1.2, 0.05}, {15, 200, 1.0, 0.035}, {-5, 230, 1.0, 0.025}};
  const FilletImage f = synthetic_fillet(std::log(3600.0), -0.03, bones, 3);
  InspectionParams p = params();
  p.band_extremes = true;
  TextureCovariance white(8);
  std::mt19937_64 rng(9);
  std::normal_distribution<float> g;
  std::vector<float> z(120 * 120);
  std::vector<uint8_t> all(z.size(), 1);
  for (int k = 0; k < 4; ++k) {
    for (float& x : z) x = g(rng);
    white.add(z.data(), all.data(), 120, 120);
  }
  std::vector<LearnedDetection> sets(3);
  const double level[3] = {4, 7, 12};
  for (int k = 0; k < 3; ++k) {
    LearnedDetection& L = sets[size_t(k)];
    L.band_edges_mm = {0, 10, 1000};  // the thick band's thresholds 1.5 higher
    L.spread_by_thickness = true;
    L.rim_walls = true;
    L.matched = learn_matched_kernels(white, {1.5, 2}, 0.4, 0.4, 0);
    for (int s = 0; s < kStatistics; ++s)
      L.stats[size_t(s)].thresholds = {level[k], level[k] + 1.5};
  }
  auto one_by_one = [&](const FilletImage& img, const std::vector<LearnedDetection>& ls) {
    std::vector<FilletResult> out;
    for (const LearnedDetection& L : ls) {
      InspectionParams q = p;
      q.learned = L;
      out.push_back(inspect_fillet(img, q, false));
    }
    return out;
  };
  const std::vector<FilletResult> each = inspect_fillet_each(f, p, sets);
  const std::vector<FilletResult> own = one_by_one(f, sets);
  ASSERT_EQ(each.size(), 3u);
  for (size_t k = 0; k < 3; ++k) expect_same_decision(each[k], own[k], "shared statistics");
  std::printf("fragments found under thresholds 4, 7, 12: %zu, %zu, %zu\n", own[0].fragments.size(),
              own[1].fragments.size(), own[2].fragments.size());
  EXPECT_GT(own[0].fragments.size(), own[2].fragments.size());  // the sets decide apart
  EXPECT_FALSE(own[2].fragments.empty());

  // Sets that read other statistics (no rim carried) are inspected one by one, and a fillet
  // the fail-safe keeps but searches (too much of it without thickness) alike.
  sets[1].rim_walls = false;
  const FilletImage holed = holes(f);
  for (const FilletImage* img : {&f, &holed}) {
    const std::vector<FilletResult> e = inspect_fillet_each(*img, p, sets);
    const std::vector<FilletResult> o = one_by_one(*img, sets);
    for (size_t k = 0; k < 3; ++k) expect_same_decision(e[k], o[k], "one by one, fail-safe");
  }
  EXPECT_EQ(inspect_fillet_each(holed, p, sets)[0].decision, Decision::kNotInspected);
}

TEST(Inspection, PlantedFragmentsFoundWithinOneMillimetre) {
  const std::vector<Bone> bones = {
      {-20, 130, 1.2, 0.15}, {5, 160, 2.0, 0.10}, {15, 200, 3.5, 0.08}};
  const FilletImage f = synthetic_fillet(std::log(3600.0), -0.03, bones, 2);
  const FilletResult r = inspect_fillet(f, params(), false);
  EXPECT_EQ(r.decision, Decision::kReject);
  ASSERT_EQ(r.fragments.size(), bones.size()) << r.reason;
  for (const Bone& b : bones) {
    double best = 1e9;
    for (const Blob& d : r.fragments)
      best = std::min(best, std::hypot(d.x_mm - b.x_mm, d.y_mm - b.y_mm));
    EXPECT_LE(best, 1.0) << "bone at " << b.x_mm << ", " << b.y_mm;
  }
  for (const Blob& d : r.fragments) {
    EXPECT_LT(d.peak_z, -5.0);
    EXPECT_GT(d.attenuation_mm2, 0.0);
  }
}

TEST(Inspection, AirPocketIsReportedNotRejected) {
  const FilletImage f = synthetic_fillet(std::log(3600.0), -0.03, {{0, 150, 2.5, -0.12}}, 3);
  const FilletResult r = inspect_fillet(f, params(), false);
  EXPECT_EQ(r.decision, Decision::kPass);
  ASSERT_EQ(r.air_pockets.size(), 1u);
  EXPECT_NEAR(r.air_pockets[0].x_mm, 0, 1.0);
  EXPECT_NEAR(r.air_pockets[0].y_mm, 150, 1.0);
}

TEST(Inspection, FailSafeCasesAreNotInspected) {
  const FilletImage good = synthetic_fillet(std::log(3600.0), -0.03, {}, 4);
  struct Case {
    const char* what;
    std::function<void(FilletImage&, InspectionParams&)> spoil;
    const char* reason;
  };
  const std::vector<Case> cases = {
      {"missing lines", [](FilletImage& f, InspectionParams&) { f.missing_lines = 2; },
       "lines missing"},
      {"invalid thickness",
       [](FilletImage& f, InspectionParams&) {
         for (size_t i = 0; i < f.size(); i += 10) f.thickness[i] = NAN;
         f.invalid_thickness_px = int(f.size() / 10);
       },
       "has no thickness"},
      {"lane edge", [](FilletImage& f, InspectionParams&) { f.touches_lane_edge = true; },
       "edge of the lane"},
      {"calibration", [](FilletImage& f, InspectionParams&) { f.calibration_mismatch = true; },
       "calibration mismatch"},
      {"no convergence", [](FilletImage&, InspectionParams& p) { p.max_iter = 2; },
       "did not converge"},
      {"empty fillet",
       [](FilletImage& f, InspectionParams&) { std::fill(f.mask.begin(), f.mask.end(), 0); },
       "too few fillet pixels"},
  };
  for (const Case& c : cases) {
    FilletImage f = good;
    InspectionParams p = params();
    c.spoil(f, p);
    for (bool baseline : {false, true}) {
      if (baseline && std::string(c.what) == "no convergence")
        continue;  // the baseline fits nothing
      const FilletResult r =
          baseline ? inspect_fillet_xray_only(f, p, false) : inspect_fillet(f, p, false);
      EXPECT_EQ(r.decision, Decision::kNotInspected) << c.what;
      EXPECT_NE(r.reason.find(c.reason), std::string::npos) << c.what << ": " << r.reason;
    }
  }
}

TEST(Inspection, AFailSafeFilletIsStillSearchedWhereWhatItHasIsWhole) {
  // Not inspected stays not inspected (a reject), but a bone in the part that has thickness
  // is named, so the plant trims the fillet rather than sending it round again; a fillet
  // whose thickness is wrong or whose lines are missing is not searched at all.
  const std::vector<Bone> bone = {{5, 160, 2.5, 0.10}};
  const FilletImage bony = synthetic_fillet(std::log(3600.0), -0.03, bone, 2);
  const FilletImage clean = synthetic_fillet(std::log(3600.0), -0.03, {}, 2);
  const InspectionParams p = params();
  const FilletResult r = inspect_fillet(holes(bony), p, false);
  EXPECT_EQ(r.decision, Decision::kNotInspected);
  EXPECT_NE(r.reason.find("has no thickness; 1 bone fragment where it has thickness"),
            std::string::npos)
      << r.reason;
  ASSERT_EQ(r.fragments.size(), 1u);
  EXPECT_LE(std::hypot(r.fragments[0].x_mm - 5, r.fragments[0].y_mm - 160), 1.0);
  EXPECT_TRUE(r.extremes.empty());  // learning and drift see passed fillets only

  const FilletResult c = inspect_fillet(holes(clean), p, false);
  EXPECT_EQ(c.decision, Decision::kNotInspected);
  EXPECT_TRUE(c.fragments.empty());
  EXPECT_EQ(c.reason.find("bone fragment"), std::string::npos) << c.reason;

  FilletImage edge = bony;
  edge.touches_lane_edge = true;
  const FilletResult e = inspect_fillet(edge, p, false);
  EXPECT_EQ(e.decision, Decision::kNotInspected);
  EXPECT_EQ(e.fragments.size(), 1u) << e.reason;
  // The X-ray-only baseline searches it alike, so that the two compare on the same footing.
  const FilletResult base = inspect_fillet_xray_only(holes(bony), p, false);
  EXPECT_EQ(base.decision, Decision::kNotInspected);
  EXPECT_NE(base.reason.find("has no thickness"), std::string::npos) << base.reason;
  EXPECT_TRUE(base.extremes.empty());
  EXPECT_EQ(base.fragments.size(), 1u) << base.reason;

  for (auto spoil : {+[](FilletImage& f) { f.calibration_mismatch = true; },
                     +[](FilletImage& f) { f.missing_lines = 2; }}) {
    FilletImage f = bony;
    spoil(f);
    const FilletResult s = inspect_fillet(f, p, false);
    EXPECT_EQ(s.decision, Decision::kNotInspected);
    EXPECT_TRUE(s.fragments.empty()) << s.reason;
    EXPECT_FALSE(s.fitted);
  }
}

TEST(Inspection, XrayOnlyBaselineSeesThicknessAsStructure) {
  // Without thickness the dome leaves structure behind: the residual spread is far larger.
  const FilletImage f = synthetic_fillet(std::log(3600.0), -0.03, {}, 5);
  const FilletResult ours = inspect_fillet(f, params(), false);
  const FilletResult base = inspect_fillet_xray_only(f, params(), false);
  EXPECT_GT(base.resid_std_dn, 1.5 * ours.resid_std_dn);
}
