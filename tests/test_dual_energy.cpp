// Dual energy with the laser's thickness: NIST's coefficients as tabulated, the step-wedge
// calibration (recovering the wedge within 1 % on a scan it was not fitted to), and the
// decomposition of rays through each material against the simulator's truth, within the
// uncertainty it states (the pull (t - truth) / sigma: mean near 0, spread near 1).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "calib/dual_energy_fit.h"
#include "calib/wedge_scan_file.h"
#include "core/error.h"
#include "pipeline/dual_energy.h"
#include "pipeline/fat_fraction.h"
#include "pipeline/inspection.h"
#include "pipeline/masked_smooth.h"
#include "pipeline/robust_fit.h"
#include "sim/dual_energy_phantom.h"
#include "temp_dir.h"

namespace rangex {
namespace {

TEST(XrayMaterials, NistValuesAtTabulatedEnergiesAndLogLogBetween) {
  EXPECT_DOUBLE_EQ(mass_attenuation(Material::kLean, 40), 0.2685);
  EXPECT_DOUBLE_EQ(mass_attenuation(Material::kBone, 60), 0.3148);
  EXPECT_DOUBLE_EQ(mass_attenuation(Material::kAluminium, 30), 1.128);
  // Between 40 and 50 keV: log-log, so below the straight line between them.
  const double m45 = mass_attenuation(Material::kFat, 45);
  EXPECT_LT(m45, 0.5 * (0.2396 + 0.2123));
  EXPECT_GT(m45, 0.2123);
  // CsI's K-edge at 33.17 keV: a jump.
  EXPECT_GT(mass_attenuation(Material::kCsI, 33.5), 2.5 * mass_attenuation(Material::kCsI, 33.0));
  // Cartilage is soft tissue, denser; fully calcified bone is cortical bone.
  EXPECT_NEAR(
      attenuation_per_mm(Material::kCartilage, 50) / attenuation_per_mm(Material::kLean, 50),
      1.10 / 1.05, 1e-12);
  EXPECT_DOUBLE_EQ(bone_attenuation_per_mm(1, 50), attenuation_per_mm(Material::kBone, 50));
  EXPECT_EQ(material_named("fat"), Material::kFat);
  EXPECT_THROW(material_named("gristle"), Error);
  EXPECT_THROW(mass_attenuation(Material::kLean, 200), Error);
}

TEST(SandwichDetector, TheBackLayerSeesTheHarderBeam) {
  const LayerSpectra s = layer_spectra({});
  EXPECT_GT(s.high_mean_kev, s.low_mean_kev + 10);
  double lo = 0, hi = 0;
  for (size_t k = 0; k < s.kev.size(); ++k) lo += s.low[k], hi += s.high[k];
  EXPECT_NEAR(lo, 1, 1e-9);
  EXPECT_NEAR(hi, 1, 1e-9);
  SandwichDetector bad;
  bad.kvp = 300;
  EXPECT_THROW(layer_spectra(bad), Error);
}

TEST(SandwichDetector, FourTimesTheDoseHalvesTheCountsNoise) {
  SandwichDetector d;
  const sim::DualEnergyRenderer nominal(d);
  d.low_photons *= 4;
  const sim::DualEnergyRenderer more(d);
  sim::RayMaterials r;
  r.lean = 20, r.fat = 3;
  double m1[2], m4[2], v1[2], v4[2];
  nominal.mean(r, &m1[0], &m1[1], &v1[0], &v1[1]);
  more.mean(r, &m4[0], &m4[1], &v4[0], &v4[1]);
  // The means do not depend on the dose; the counts' variance (less the electronics') does.
  const double en2 = sim::DualEnergyRenderParams{}.electronic_noise *
                     sim::DualEnergyRenderParams{}.electronic_noise;
  for (int l = 0; l < 2; ++l) {
    EXPECT_DOUBLE_EQ(m1[l], m4[l]);
    EXPECT_NEAR((v4[l] - en2) / (v1[l] - en2), 0.25, 1e-12);
  }
}

struct Calibrated {
  sim::DualEnergyRenderer detector{SandwichDetector{}};
  WedgeScan scan = sim::simulate_wedge_scan(detector, 1);
  DualEnergyFit fit = fit_dual_energy(scan, SandwichDetector{}, 0.05);
};

const Calibrated& calibrated() {
  static const Calibrated c;
  return c;
}

// The worst relative error of the wedge's steps taken back through p: A-150 steps of at
// least min_a150 mm, aluminium steps of at least 1 mm.
void worst_recovery(const DualEnergyParams& p, const WedgeScan& scan, double min_a150,
                    double* worst_a, double* worst_b) {
  *worst_a = *worst_b = 0;
  for (const DualEnergyFit::Step& s : evaluate_wedge(p, scan)) {
    if (s.a150_mm >= min_a150)
      *worst_a = std::max(*worst_a, std::abs(s.a_fit - s.a150_mm) / s.a150_mm);
    if (s.al_mm >= 1) *worst_b = std::max(*worst_b, std::abs(s.b_fit - s.al_mm) / s.al_mm);
  }
}

TEST(DualEnergyCalibration, RecoversTheWedgeWithinOnePercentOnAnotherScan) {
  const Calibrated& c = calibrated();
  std::printf("%s", dual_energy_report(c.fit).c_str());
  EXPECT_LT(c.fit.a_worst_rel, 0.01);
  EXPECT_LT(c.fit.b_worst_rel, 0.01);
  // A second scan of the same wedge, other noise: the fit was not made on it.
  const WedgeScan other = sim::simulate_wedge_scan(c.detector, 2);
  double worst_a, worst_b;
  worst_recovery(c.fit.params, other, 5, &worst_a, &worst_b);
  std::printf("another scan: worst A-150 step %.3f %%, worst aluminium step %.3f %%\n",
              100 * worst_a, 100 * worst_b);
  EXPECT_LT(worst_a, 0.01);
  EXPECT_LT(worst_b, 0.01);
  // The noise the scan shows is the detector's (var = gain x DN + electronic).
  double m, mh, v;
  c.detector.mean({}, &m, &mh, &v, nullptr);
  EXPECT_NEAR(c.fit.params.gain_low * m + c.fit.params.var_e_low, v, 0.1 * v);
}

TEST(DualEnergyCalibration, RefusesAScanItCannotFit) {
  WedgeScan s = calibrated().scan;
  s.steps.resize(12);
  EXPECT_THROW(fit_dual_energy(s, {}, 0.05), Error);
  s = calibrated().scan;
  s.open_low = 0;
  EXPECT_THROW(fit_dual_energy(s, {}, 0.05), Error);
  s = calibrated().scan;
  s.steps[3].high = 0;
  EXPECT_THROW(fit_dual_energy(s, {}, 0.05), Error);
  // Plenty of steps, but of one aluminium thickness: the fit is not determined.
  s = calibrated().scan;
  std::vector<WedgeStep> flat;
  for (const WedgeStep& st : s.steps)
    if (st.al_mm == 2) flat.insert(flat.end(), 4, st);
  s.steps = flat;
  try {
    fit_dual_energy(s, {}, 0.05);
    ADD_FAILURE() << "a wedge of one aluminium thickness was fitted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("must cross both thicknesses"), std::string::npos)
        << e.what();
  }
}

// Rays through `r`, decomposed; the lengths' pulls against `truth` (lean, fat, bone).
struct Pulls {
  double mean[3] = {0, 0, 0}, sd[3] = {0, 0, 0}, err[3] = {0, 0, 0}, sigma[3] = {0, 0, 0};
};
Pulls decompose_rays(const sim::RayMaterials& r, const double truth[3], double laser_mm,
                     uint64_t seed, int n = 3000) {
  const Calibrated& c = calibrated();
  sim::Rng rng(seed, 7);
  const size_t N = static_cast<size_t>(n);
  std::vector<uint16_t> lo(N), hi(N);
  std::vector<float> open_lo(N, float(c.scan.open_low)), open_hi(N, float(c.scan.open_high)), t(N);
  const double total = r.lean + r.fat + r.cartilage + r.tendon + r.bone;
  double m_lo, m_hi, v_lo, v_hi;
  c.detector.mean(r, &m_lo, &m_hi, &v_lo, &v_hi);
  for (int k = 0; k < n; ++k) {
    sim::DualEnergyRenderer::draw(m_lo, m_hi, v_lo, v_hi, rng, &lo[size_t(k)], &hi[size_t(k)]);
    t[size_t(k)] = float(total + laser_mm * rng.normal());  // the laser's own noise
  }
  DualEnergyBatch b;
  b.low = lo.data(), b.high = hi.data(), b.open_low = open_lo.data(), b.open_high = open_hi.data(),
  b.thickness = t.data(), b.pixels = n;
  std::vector<float> len(3 * size_t(n)), sd(3 * size_t(n));
  dual_energy_decompose(b, c.fit.params, len.data(), sd.data());
  Pulls p;
  for (int m = 0; m < 3; ++m) {
    double s = 0, s2 = 0, e = 0, sg = 0;
    for (int k = 0; k < n; ++k) {
      const double pull =
          (len[3 * size_t(k) + size_t(m)] - truth[m]) / sd[3 * size_t(k) + size_t(m)];
      s += pull, s2 += pull * pull;
      e += len[3 * size_t(k) + size_t(m)] - truth[m];
      sg += sd[3 * size_t(k) + size_t(m)];
    }
    p.mean[m] = s / n;
    p.sd[m] = std::sqrt(s2 / n - p.mean[m] * p.mean[m]);
    p.err[m] = e / n;
    p.sigma[m] = sg / n;
  }
  return p;
}

void expect_within_stated(const char* what, const Pulls& p) {
  const char* names[3] = {"lean", "fat", "bone"};
  for (int m = 0; m < 3; ++m) {
    std::printf("%-28s %-4s mean error %+7.3f mm, stated sigma %.3f mm, pull mean %+.2f sd %.2f\n",
                what, names[m], p.err[m], p.sigma[m], p.mean[m], p.sd[m]);
    EXPECT_LT(std::abs(p.mean[m]), 0.5) << what << " " << names[m];
    EXPECT_GT(p.sd[m], 0.7) << what << " " << names[m];
    EXPECT_LT(p.sd[m], 1.3) << what << " " << names[m];
  }
}

// A ray through lean, fat and fully calcified bone, checked against those lengths.
void expect_ray(const char* what, double lean, double fat, double bone, uint64_t seed) {
  sim::RayMaterials r;
  r.lean = lean, r.fat = fat, r.bone = bone;
  const double truth[3] = {lean, fat, bone};
  expect_within_stated(what, decompose_rays(r, truth, 0.05, seed));
}

TEST(DualEnergyDecomposition, LeanAndFatSlabsMatchTheirTruth) {
  expect_ray("25 mm lean", 25, 0, 0, 1);
  expect_ray("15 mm fat", 0, 15, 0, 2);
  expect_ray("18 lean + 7 fat", 18, 7, 0, 3);
}

TEST(DualEnergyDecomposition, BoneInMeatMatchesItsTruth) {
  expect_ray("20 lean + 2 mm bone", 20, 0, 2, 4);
  expect_ray("30 lean + 5 fat + 1 bone", 30, 5, 1, 5);
}

TEST(DualEnergyDecomposition, CartilageAndTendonReadAsNoBone) {
  // Soft tissue denser than lean: more attenuation at both energies alike. With the laser's
  // thickness it comes out as less bone than none, never as bone.
  sim::RayMaterials r;
  r.lean = 20, r.cartilage = 6;
  const double none[3] = {0, 0, 0};
  const Pulls c = decompose_rays(r, none, 0.05, 6);
  r.cartilage = 0, r.tendon = 6;
  const Pulls t = decompose_rays(r, none, 0.05, 7);
  std::printf("20 lean + 6 cartilage: bone %+.3f mm; + 6 tendon: bone %+.3f mm (sigma %.2f)\n",
              c.err[2], t.err[2], c.sigma[2]);
  EXPECT_LT(c.err[2], 0.02);
  EXPECT_LT(t.err[2], 0.02);
}

TEST(DualEnergyDecomposition, PartlyCalcifiedBoneReadsAsItsCalcifiedShare) {
  for (const double c : {0.3, 0.6}) {
    sim::RayMaterials r;
    r.lean = 20, r.bone = 3, r.calcification = c;
    const double none[3] = {0, 0, 0};
    const Pulls p = decompose_rays(r, none, 0.05, uint64_t(10 * c));
    const double bone = p.err[2];  // truth 0: the error is the reading
    std::printf("3 mm bone calcified %.1f in 20 lean: %.3f mm of cortical bone (c x 3 = %.2f)\n", c,
                bone, 3 * c);
    // Its uncalcified part is cartilage (read as a little less than none).
    EXPECT_GT(bone, 0.8 * c * 3);
    EXPECT_LT(bone, 1.05 * c * 3);
  }
}

// A patch of fillet, 80 x 80 pixels: its thickness a smooth bump (15-25 mm), its fat share
// rising across it (10 % to 25 %), a fragment of fully calcified bone (2 mm through, 9 pixels
// across) in the middle. Full decomposition, the fat's share smoothed, then bone given it.
TEST(DualEnergyDecomposition, BoneGivenTheSmoothFatShareIsPreciseAndTrue) {
  const Calibrated& c = calibrated();
  constexpr int R = 80, C = 80, N = R * C;
  std::vector<uint16_t> lo(N), hi(N);
  std::vector<float> open_lo(N, float(c.scan.open_low)), open_hi(N, float(c.scan.open_high)), T(N),
      phi_true(N), bone_true(N);
  std::vector<uint8_t> mask(N, 1);
  sim::Rng rng(11, 3);
  for (int r = 0; r < R; ++r)
    for (int q = 0; q < C; ++q) {
      const int p = r * C + q;
      const double dr = (r - 40) / 40.0, dq = (q - 40) / 40.0;
      const double t = 15 + 10 * std::exp(-(dr * dr + dq * dq));
      const double phi = 0.10 + 0.15 * q / (C - 1.0);
      const bool in_bone = (r - 40) * (r - 40) + (q - 40) * (q - 40) <= 16;
      sim::RayMaterials m;
      m.bone = in_bone ? 2 : 0;
      m.lean = (1 - phi) * (t - m.bone), m.fat = phi * (t - m.bone);
      double mlo, mhi, vlo, vhi;
      c.detector.mean(m, &mlo, &mhi, &vlo, &vhi);
      sim::DualEnergyRenderer::draw(mlo, mhi, vlo, vhi, rng, &lo[size_t(p)], &hi[size_t(p)]);
      T[size_t(p)] = float(t + 0.05 * rng.normal());
      phi_true[size_t(p)] = float(phi);
      bone_true[size_t(p)] = float(m.bone);
    }
  DualEnergyBatch b;
  b.low = lo.data(), b.high = hi.data(), b.open_low = open_lo.data(), b.open_high = open_hi.data(),
  b.thickness = T.data(), b.pixels = N;
  std::vector<float> basis(5 * N), len(3 * N), sd(3 * N), bone(N), bone_sd(N), phi, phi_var;
  dual_energy_basis(b, c.fit.params, basis.data());
  dual_energy_lengths(basis.data(), T.data(), N, c.fit.params, len.data(), sd.data());
  fat_fraction_map(len.data(), sd.data(), mask.data(), R, C, 12, phi, phi_var);
  dual_energy_bone(basis.data(), T.data(), phi.data(), phi_var.data(), N, c.fit.params, bone.data(),
                   bone_sd.data());
  // Away from the patch's edges (the smoothing's reach) and the fragment.
  double phi_err = 0, phi_pull = 0, pull = 0, pull2 = 0, full_sd = 0, gls_sd = 0, frag = 0;
  int n = 0, nf = 0;
  for (int r = 15; r < R - 15; ++r)
    for (int q = 15; q < C - 15; ++q) {
      const size_t p = size_t(r * C + q);
      if (bone_true[p] > 0) {
        frag += bone[p], ++nf;
        continue;
      }
      phi_err = std::max(phi_err, double(std::abs(phi[p] - phi_true[p])));
      phi_pull = std::max(phi_pull, std::abs(phi[p] - phi_true[p]) / std::sqrt(double(phi_var[p])));
      const double z = bone[p] / bone_sd[p];
      pull += z, pull2 += z * z;
      full_sd += sd[3 * p + 2], gls_sd += bone_sd[p];
      ++n;
    }
  pull /= n;
  const double pull_sd = std::sqrt(pull2 / n - pull * pull);
  frag /= nf;
  std::printf(
      "fat share: worst error %.3f (%.1f of its sigma); bone sigma a pixel: %.3f mm full, %.3f mm "
      "given the fat "
      "share; pull mean %+.2f sd %.2f; the fragment reads %.3f mm (2 mm)\n",
      phi_err, phi_pull, full_sd / n, gls_sd / n, pull, pull_sd, frag);
  EXPECT_LT(phi_err, 0.08);
  EXPECT_LT(phi_pull, 4.5);  // the worst of 2,500 correlated pixels
  EXPECT_LT(gls_sd / n, 0.25 * full_sd / n);
  // The fat share's error is smooth: it moves a whole region's pulls together, so their mean
  // is one draw of it (within its sigma), not an average of independent ones.
  EXPECT_LT(std::abs(pull), 1.0);
  EXPECT_GT(pull_sd, 0.8);
  EXPECT_LT(pull_sd, 1.2);
  EXPECT_NEAR(frag, 2.0, 0.1);
}

// The wedge as a plant scans it: lines of both layers through the lane's fan (each ray slanted
// through the slabs), written and read back as a scan folder, fitted, and a second scan of it
// taken back within 1 % at every step of 1 mm or more.
TEST(DualEnergyWedgeScan, AScanOnTheBeltCalibratesWithinOnePercent) {
  test::TempDir t;
  const FanBeam beam;
  const sim::DualEnergyRenderer det{SandwichDetector{}};
  const WedgeLayout w;
  std::vector<uint16_t> lo, hi;
  sim::render_wedge_lines(det, beam, w, 1, lo, hi);
  write_wedge_scan((t.path() / "fit").string(), w, beam.pixels, lo, hi);
  sim::render_wedge_lines(det, beam, w, 2, lo, hi);
  write_wedge_scan((t.path() / "other").string(), w, beam.pixels, lo, hi);
  const WedgeScan scan = read_wedge_scan((t.path() / "fit").string(), beam);
  ASSERT_EQ(scan.steps.size(), w.a150_mm.size() * w.al_mm.size());
  // The slant: a step's thickness along its rays is the drawing's / cos(theta) (> 1).
  EXPECT_GT(scan.steps.back().a150_mm, 60.0);
  EXPECT_LT(scan.steps.back().a150_mm, 60.0 * 1.01);
  const DualEnergyFit f = fit_dual_energy(scan, SandwichDetector{}, 0.1);
  double worst_a, worst_b;
  worst_recovery(f.params, read_wedge_scan((t.path() / "other").string(), beam), 1, &worst_a,
                 &worst_b);
  std::printf("wedge scan on the belt, another scan: worst A-150 %.2f %%, aluminium %.2f %%\n",
              100 * worst_a, 100 * worst_b);
  EXPECT_LT(worst_a, 0.01);
  EXPECT_LT(worst_b, 0.01);
}

TEST(DualEnergyWedgeScan, AWedgeNotWhereItsDrawingSaysIsRefused) {
  test::TempDir t;
  const FanBeam beam;
  const sim::DualEnergyRenderer det{SandwichDetector{}};
  WedgeLayout w;
  w.step_lines = 200;
  std::vector<uint16_t> lo, hi;
  sim::render_wedge_lines(det, beam, w, 1, lo, hi);
  WedgeLayout drawn = w;
  drawn.first_pixel += w.step_pixels / 2;  // the drawing half a step off the wedge
  write_wedge_scan((t.path() / "s").string(), drawn, beam.pixels, lo, hi);
  try {
    read_wedge_scan((t.path() / "s").string(), beam);
    ADD_FAILURE() << "a misplaced wedge was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not where wedge.yaml puts it"), std::string::npos)
        << e.what();
  }
  FanBeam other = beam;
  other.pixels = 480;
  EXPECT_THROW(read_wedge_scan((t.path() / "s").string(), other), Error);
  EXPECT_THROW(read_wedge_scan((t.path() / "none").string(), beam), Error);
}

// A fillet of both lines as the assembly cuts it, rendered ray by ray through the sandwich:
// lean and fat (its share rising across it), a calcified fragment, a lump of cartilage, an
// air pocket and a lump of fat; the belt around it.
struct DualFillet {
  FilletImage img;
  double bone_mg = 0;  // the fragment's true bone-equivalent mass
  int bone_r = 0, bone_c = 0;
};

// blur_px: the detector's line spread across it (Gaussian), on both layers' readings.
DualFillet dual_fillet(uint64_t seed, bool fragment, double blur_px = 0) {
  const Calibrated& c = calibrated();
  DualFillet d;
  FilletImage& f = d.img;
  f.rows = 150, f.cols = 110;
  f.pitch_mm = f.step_mm = 0.4;
  f.has_dual_energy = true;
  f.dual_energy = c.fit.params;
  const size_t n = f.size();
  f.xray.resize(n), f.xray_high.resize(n), f.thickness.resize(n), f.mask.resize(n);
  sim::Rng rng(seed, 5);
  d.bone_r = 50, d.bone_c = 40;
  std::vector<double> mean[4];  // low, high, their variances
  for (auto& v : mean) v.resize(n);
  for (int r = 0; r < f.rows; ++r)
    for (int q = 0; q < f.cols; ++q) {
      const size_t p = size_t(r) * f.cols + q;
      const double er = (r - 75) / 68.0, eq = (q - 55) / 48.0, e = er * er + eq * eq;
      const double t = e < 1 ? 4 + 20 * std::sqrt(1 - e) : 0;
      sim::RayMaterials m;
      auto lump = [&](int r0, int q0, double radius) {
        const double dr = (r - r0) * 0.4, dq = (q - q0) * 0.4,
                     h = radius * radius - dr * dr - dq * dq;
        return h > 0 ? 2 * std::sqrt(h) : 0.0;
      };
      const double bone = fragment ? lump(d.bone_r, d.bone_c, 1.5) : 0;
      const double cart = lump(100, 70, 3.0), air = lump(110, 35, 2.5), fat = lump(40, 75, 4.0);
      const double phi = 0.05 + 0.15 * q / (f.cols - 1.0);
      const double meat = std::max(0.0, t - bone - cart - air - fat);
      m.lean = (1 - phi) * meat, m.fat = phi * meat + (t > 0 ? fat : 0);
      m.bone = t > 0 ? bone : 0;
      m.cartilage = t > 0 ? cart : 0;
      d.bone_mg += m.bone * 0.4 * 0.4 * 1.92;
      c.detector.mean(m, &mean[0][p], &mean[1][p], &mean[2][p], &mean[3][p]);
      f.thickness[p] = float(t > 0 ? t + 0.05 * rng.normal() : 0.02 * rng.normal());
      f.mask[p] = t > 1.5;
    }
  f.detector_sigma_px = blur_px;
  for (int r = 0; r < f.rows; ++r)
    for (int q = 0; q < f.cols; ++q) {
      double b[4] = {0, 0, 0, 0}, wsum = 0;
      const int R = blur_px > 0 ? int(std::ceil(4 * blur_px)) : 0;
      for (int k = -R; k <= R; ++k) {
        const int qq = std::clamp(q + k, 0, f.cols - 1);
        const double w = R ? std::exp(-0.5 * k * k / (blur_px * blur_px)) : 1.0;
        for (int j = 0; j < 4; ++j) b[j] += w * mean[j][size_t(r) * f.cols + qq];
        wsum += w;
      }
      const size_t p = size_t(r) * f.cols + q;
      sim::DualEnergyRenderer::draw(b[0] / wsum, b[1] / wsum, b[2] / wsum, b[3] / wsum, rng,
                                    &f.xray[p], &f.xray_high[p]);
    }
  return d;
}

TEST(DualEnergyInspection, FindsTheFragmentAndNeitherCartilageNorAirNorFat) {
  InspectionParams p;
  const DualFillet d = dual_fillet(3, true);
  const FilletResult r = inspect_fillet(d.img, p, true);
  ASSERT_EQ(r.decision, Decision::kReject) << r.reason;
  EXPECT_TRUE(r.dual_energy);
  for (const Blob& f : r.fragments)
    std::printf("fragment rows %d-%d cols %d-%d peak z %.1f, %.2f mg\n", f.row0, f.row1, f.col0,
                f.col1, f.peak_z, f.bone_mg);
  ASSERT_EQ(r.fragments.size(), 1u);
  const Blob& b = r.fragments[0];
  EXPECT_NEAR(b.row0 + 0.5 * (b.row1 - b.row0), d.bone_r, 3);
  EXPECT_NEAR(b.col0 + 0.5 * (b.col1 - b.col0), d.bone_c, 3);
  // Its mass: the thresholded blob holds most of it (the fragment's rim is below the noise).
  std::printf("fragment: %.2f mg read, %.2f mg true; peak z %.1f\n", b.bone_mg, d.bone_mg,
              b.peak_z);
  EXPECT_GT(b.bone_mg, 0.6 * d.bone_mg);
  EXPECT_LT(b.bone_mg, 1.15 * d.bone_mg);
  // The images a record keeps: bone and the fat share, which follows the truth's gradient.
  ASSERT_EQ(r.bone_mm.size(), d.img.size());
  ASSERT_EQ(r.fat_share.size(), d.img.size());
  const float left = r.fat_share[size_t(75) * d.img.cols + 25],
              right = r.fat_share[size_t(75) * d.img.cols + 85];
  EXPECT_NEAR(left, 0.05 + 0.15 * 25 / 109.0, 0.06);
  EXPECT_NEAR(right, 0.05 + 0.15 * 85 / 109.0, 0.06);
  // Without the fragment: nothing, though the cartilage, air and fat are there.
  const FilletResult clean = inspect_fillet(dual_fillet(4, false).img, p, false);
  EXPECT_EQ(clean.decision, Decision::kPass) << clean.reason;
  EXPECT_TRUE(clean.fragments.empty());
}

// The detector's blur across the fillet's steep sides: without matching the thickness to
// it, the rim reads as bone; matched (as at one energy), the clean fillet passes.
TEST(DualEnergyInspection, TheThicknessIsMatchedToTheDetectorsBlur) {
  InspectionParams p;
  const DualFillet blurred = dual_fillet(4, false, 1.2);
  const FilletResult matched = inspect_fillet(blurred.img, p, true);
  FilletImage unmatched_img = blurred.img;
  unmatched_img.detector_sigma_px = 0;
  const FilletResult unmatched = inspect_fillet(unmatched_img, p, true);
  // The bone image's extremes on the fillet's rim (the outer 3 px of the mask).
  auto rim_extreme = [&](const FilletResult& r) {
    const FilletImage& f = blurred.img;
    double worst = 0;
    for (int row = 3; row < f.rows - 3; ++row)
      for (int q = 3; q < f.cols - 3; ++q) {
        const size_t i = size_t(row) * f.cols + q;
        if (!f.mask[i] || !std::isfinite(r.bone_mm[i])) continue;
        if (f.mask[i - 3] && f.mask[i + 3] && f.mask[i - 3 * f.cols] && f.mask[i + 3 * f.cols])
          continue;
        worst = std::max(worst, std::abs(double(r.bone_mm[i])));
      }
    return worst;
  };
  std::printf("rim |bone| at most %.3f mm matched, %.3f mm not\n", rim_extreme(matched),
              rim_extreme(unmatched));
  EXPECT_LT(rim_extreme(matched), 0.7 * rim_extreme(unmatched));
  EXPECT_EQ(matched.decision, Decision::kPass) << matched.reason;
  EXPECT_TRUE(matched.fragments.empty());
}

// Each fillet smooths its fat share at the scale whose bone image, as the detection smooths
// it, spreads least: the inspection's bone image is that of the best of the three scales
// forced one at a time, and the fragment is still read.
TEST(DualEnergyInspection, EachFilletChoosesTheFatShareScaleThatSpreadsLeast) {
  const DualFillet d = dual_fillet(5, true);
  const InspectionParams p;
  auto spread = [&](const FilletResult& r) {
    std::vector<float> s;
    masked_gaussian(r.bone_mm.data(), d.img.mask.data(), d.img.rows, d.img.cols, p.smooth_sigma_px,
                    s);
    std::vector<double> v;
    for (size_t i = 0; i < d.img.size(); ++i)
      if (d.img.mask[i] && std::isfinite(s[i])) v.push_back(s[i]);
    const double m = median_inplace(v.data(), v.size());
    for (double& e : v) e = std::abs(e - m);
    return 1.4826 * median_inplace(v.data(), v.size());
  };
  double best = 1e9;
  for (double px : {12.0, 24.0, 48.0}) {
    InspectionParams forced = p;
    forced.fat_share_sigma_px = px;
    forced.fat_share_scales = 1;
    const double s = spread(inspect_fillet(d.img, forced, true));
    std::printf("fat share over %.0f px: the bone image spreads %.4f mm\n", px, s);
    best = std::min(best, s);
  }
  const FilletResult chosen = inspect_fillet(d.img, p, true);
  EXPECT_NEAR(spread(chosen), best, 1e-6);
  ASSERT_EQ(chosen.fragments.size(), 1u);
  EXPECT_GT(chosen.fragments[0].bone_mg, 0.6 * d.bone_mg);
  EXPECT_LT(chosen.fragments[0].bone_mg, 1.15 * d.bone_mg);
}

// laser_and_low_line: the laser's bone image and the low line's one-energy z, each at unit
// spread under the round kernel, summed. It finds the fragment both see, passes
// the clean fillet's cartilage, air and fat, reads the fragment's mass from the bone image,
// and fails safe when the low line's fit cannot be made.
TEST(DualEnergyInspection, LaserAndLowLineSumsWhatBothSee) {
  InspectionParams p;
  const DualFillet d = dual_fillet(3, true);
  auto peak = [&](DualEnergyMethod m) {
    p.dual_energy = m;
    const FilletResult r = inspect_fillet(d.img, p, false);
    double z = 0;
    for (const Blob& b : r.fragments) z = std::max(z, -b.peak_z);
    return std::pair{r, z};
  };
  const auto [laser, z_laser] = peak(DualEnergyMethod::kLaser);
  const auto [low, z_low] = peak(DualEnergyMethod::kLowLine);
  const auto [both, z_both] = peak(DualEnergyMethod::kLaserAndLowLine);
  std::printf("fragment's peak z: laser %.1f, low line %.1f, both %.1f\n", z_laser, z_low, z_both);
  EXPECT_TRUE(both.dual_energy);
  ASSERT_EQ(both.decision, Decision::kReject) << both.reason;
  ASSERT_EQ(both.fragments.size(), 1u);
  const Blob& b = both.fragments[0];
  EXPECT_NEAR(b.row0 + 0.5 * (b.row1 - b.row0), d.bone_r, 3);
  EXPECT_NEAR(b.col0 + 0.5 * (b.col1 - b.col0), d.bone_c, 3);
  EXPECT_GT(b.bone_mg, 0.6 * d.bone_mg);
  EXPECT_LT(b.bone_mg, 1.15 * d.bone_mg);
  // The sum stands out further than the weaker image and nearly as far as the stronger
  // (the two images' noise is partly the same: the low line's counts).
  EXPECT_GT(z_both, std::min(z_laser, z_low));
  EXPECT_GT(z_both, 0.9 * std::max(z_laser, z_low));
  EXPECT_GT(std::abs(z_both - z_low), 0.01 * z_low);  // neither image alone
  EXPECT_GT(std::abs(z_both - z_laser), 0.01 * z_laser);
  const FilletResult clean = inspect_fillet(dual_fillet(4, false).img, p, false);
  EXPECT_EQ(clean.decision, Decision::kPass) << clean.reason;
  // The low line's fit cannot settle in one iteration: not inspected, though the bone image
  // alone could be read.
  p.max_iter = 1;
  const FilletResult unfit = inspect_fillet(d.img, p, false);
  EXPECT_EQ(unfit.decision, Decision::kNotInspected);
  EXPECT_NE(unfit.reason.find("dual energy with the low line: robust fit"), std::string::npos)
      << unfit.reason;
  p.dual_energy = DualEnergyMethod::kLaser;
  EXPECT_EQ(inspect_fillet(d.img, p, false).decision, Decision::kReject);
}

TEST(DualEnergyInspection, EachMethodRunsAndFailsSafe) {
  InspectionParams p;
  DualFillet d = dual_fillet(3, true);
  p.dual_energy = DualEnergyMethod::kNoLaser;
  const FilletResult alone = inspect_fillet(d.img, p, false);
  EXPECT_TRUE(alone.dual_energy);
  EXPECT_NE(alone.decision, Decision::kNotInspected) << alone.reason;
  p.dual_energy = DualEnergyMethod::kLowLine;
  const FilletResult low = inspect_fillet(d.img, p, false);
  EXPECT_FALSE(low.dual_energy);
  EXPECT_TRUE(low.fitted);
  // No bare belt beside the fillet: its open beam cannot be read; not inspected.
  p.dual_energy = DualEnergyMethod::kLaser;
  FilletImage crowded = d.img;
  for (size_t i = 0; i < crowded.size(); ++i)
    if (!crowded.mask[i]) crowded.thickness[i] = std::numeric_limits<float>::quiet_NaN();
  crowded.invalid_thickness_px = 0;
  const FilletResult blind = inspect_fillet(crowded, p, false);
  EXPECT_EQ(blind.decision, Decision::kNotInspected);
  EXPECT_NE(blind.reason.find("open beam"), std::string::npos) << blind.reason;
  // A missing high line is never passed.
  FilletImage half = d.img;
  half.xray_high.resize(10);
  EXPECT_EQ(inspect_fillet(half, p, false).decision, Decision::kNotInspected);
  // Too much meat without thickness (far from the fragment): not inspected, but searched
  // where it has thickness, as at one energy, and the fragment named.
  FilletImage holed = d.img;
  int holes = 0;
  for (int r = 115; r < holed.rows; ++r)
    for (int q = 0; q < holed.cols; q += 2) {
      const size_t i = size_t(r) * holed.cols + q;
      if (holed.mask[i]) holed.thickness[i] = std::numeric_limits<float>::quiet_NaN(), ++holes;
    }
  holed.invalid_thickness_px = holes;
  ASSERT_GT(holes, 0.02 * holed.mask_pixels());
  const FilletResult searched = inspect_fillet(holed, p, false);
  EXPECT_TRUE(searched.dual_energy);
  EXPECT_EQ(searched.decision, Decision::kNotInspected);
  EXPECT_NE(searched.reason.find("no thickness; 1 bone fragment where it has thickness"),
            std::string::npos)
      << searched.reason;
  ASSERT_EQ(searched.fragments.size(), 1u);
  const Blob& g = searched.fragments[0];
  EXPECT_NEAR(g.row0 + 0.5 * (g.row1 - g.row0), d.bone_r, 3);
  EXPECT_NEAR(g.col0 + 0.5 * (g.col1 - g.col0), d.bone_c, 3);
  EXPECT_TRUE(searched.extremes.empty());
}

}  // namespace
}  // namespace rangex
