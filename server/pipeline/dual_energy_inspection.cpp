// A dual-energy fillet's inspection (docs/dual-energy.md): its bone image from both X-ray
// lines, with the laser's thickness (pipeline/dual_energy.h, fat_fraction.h) or without it as
// a dual-energy machine alone would (a two-material decomposition whose soft tissue is the
// fillet's own median), then the detection every inspection shares on z = -bone / sigma.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "core/no_value.h"
#include "pipeline/detector_match.h"
#include "pipeline/dual_energy.h"
#include "pipeline/fat_fraction.h"
#include "pipeline/inspection_steps.h"
#include "pipeline/masked_smooth.h"
#include "pipeline/robust_fit.h"
#include "pipeline/thickness_spread.h"

namespace rangex {

namespace {

constexpr double kBoneMgPerMm3 = 1.92;  // cortical bone (ICRU 44)
constexpr int kMinBeltPixels = 20;

// The open beam of both layers: the mean of the bare belt in the fillet's box (off the
// fillet, a thickness measured under 0.5 mm); 0 when too few such pixels.
void open_beam(const FilletImage& img, double* lo, double* hi) {
  double s_lo = 0, s_hi = 0;
  int n = 0;
  for (size_t i = 0; i < img.size(); ++i)
    if (!img.mask[i] && std::isfinite(img.thickness[i]) && img.thickness[i] < 0.5 &&
        img.xray[i] > 0 && img.xray_high[i] > 0)
      s_lo += img.xray[i], s_hi += img.xray_high[i], ++n;
  *lo = n >= kMinBeltPixels ? s_lo / n : 0;
  *hi = n >= kMinBeltPixels ? s_hi / n : 0;
}

// Without the laser: (A, B) = soft tissue t_s (1, r) + bone t_b (a_bone, b_bone), r the
// fillet's median B / A over meat thicker than 5 mm of A-150.
void bone_without_laser(const std::vector<float>& basis, const std::vector<uint8_t>& use,
                        const DualEnergyParams& k, std::vector<float>& bone,
                        std::vector<float>& sigma) {
  const size_t n = use.size();
  std::vector<double> ratios;
  for (size_t i = 0; i < n; ++i)
    if (use[i] && basis[5 * i] > 5) ratios.push_back(double(basis[5 * i + 1]) / basis[5 * i]);
  bone.assign(n, kNaN), sigma.assign(n, kNaN);
  if (ratios.empty()) return;
  const double r = median_inplace(ratios.data(), ratios.size());
  const double den = k.basis[5] - r * k.basis[4];
  for (size_t i = 0; i < n; ++i) {
    if (!use[i] || !std::isfinite(basis[5 * i])) continue;
    const double a = basis[5 * i], b = basis[5 * i + 1];
    const double va = basis[5 * i + 2], cab = basis[5 * i + 3], vb = basis[5 * i + 4];
    bone[i] = float((b - r * a) / den);
    sigma[i] = float(std::sqrt(std::max(1e-12, vb - 2 * r * cab + r * r * va)) / std::abs(den));
  }
}

// The inputs of the bone with the laser (one fillet).
struct LaserBone {
  const FilletImage& img;
  const std::vector<float>& basis;
  const std::vector<float>& thickness;
  const std::vector<float>& lengths;  // step 2's, and their sigmas
  const std::vector<float>& lsig;
  const std::vector<uint8_t>& use;
  // Tissue denser than lean (cartilage, tendon): a fat length below -3 sigma over a few
  // pixels, which no mix of lean and fat gives. It depends on step 2 alone.
  const std::vector<uint8_t>& dense;
  const DualEnergyParams& k;
  const InspectionParams& p;
};

// The pixels of tissue denser than lean (LaserBone::dense), from step 2's fat lengths.
std::vector<uint8_t> denser_than_lean(const FilletImage& img, const std::vector<float>& lengths,
                                      const std::vector<float>& lsig,
                                      const std::vector<uint8_t>& use) {
  const size_t n = img.size();
  std::vector<float> fat(n), fat_var(n), fat_s, var_s;
  for (size_t i = 0; i < n; ++i) {
    fat[i] = use[i] && std::isfinite(lengths[3 * i + 1]) ? lengths[3 * i + 1] : 0.f;
    fat_var[i] = use[i] && std::isfinite(lsig[3 * i + 1]) ? lsig[3 * i + 1] * lsig[3 * i + 1] : 0.f;
  }
  constexpr double kLocalPx = 3;
  masked_gaussian(fat.data(), use.data(), img.rows, img.cols, kLocalPx, fat_s);
  masked_gaussian(fat_var.data(), use.data(), img.rows, img.cols, kLocalPx, var_s);
  const double gain = gaussian_noise_gain(kLocalPx);
  std::vector<uint8_t> dense(n, 0);
  for (size_t i = 0; i < n; ++i)
    dense[i] = use[i] && fat_s[i] < -3 * gain * std::sqrt(std::max(0.f, var_s[i]));
  return dense;
}

// The bone given the fat share smoothed over sigma_px (steps 3 and 4), in two passes.
void bone_with_laser(const LaserBone& in, double sigma_px, std::vector<float>& bone,
                     std::vector<float>& sigma, std::vector<float>& phi,
                     std::vector<float>& phi_var) {
  const FilletImage& img = in.img;
  const size_t n = img.size();
  const std::vector<float>&basis = in.basis, &thickness = in.thickness, &lengths = in.lengths,
        &lsig = in.lsig;
  const std::vector<uint8_t>& use = in.use;
  const DualEnergyParams& k = in.k;
  fat_fraction_map(lengths.data(), lsig.data(), use.data(), img.rows, img.cols, sigma_px, phi,
                   phi_var);
  bone.assign(n, kNaN), sigma.assign(n, kNaN);
  const double dv = in.p.soft_density_sigma * in.p.soft_density_sigma;
  dual_energy_bone(basis.data(), thickness.data(), phi.data(), phi_var.data(), int(n), k,
                   bone.data(), sigma.data(), dv);
  // What is not lean and fat pulls the smoothed fat share around it and paints a halo of
  // bone there: what holds far less than the thickness promises (air pockets, lumps of
  // fat: bone below -3 sigma), and tissue denser than lean (in.dense). The fat share is
  // measured again without them (and 3 px around). A pixel reading as more bone is never
  // left out: a streak of lean would then read as bone.
  std::vector<uint8_t> soft = use;
  const int R = 3;
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      const size_t i = size_t(r) * img.cols + c;
      if (!use[i]) continue;
      if (!(bone[i] < -3 * sigma[i]) && !in.dense[i]) continue;
      for (int dr = -R; dr <= R; ++dr)
        for (int dc = -R; dc <= R; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if (rr >= 0 && rr < img.rows && cc >= 0 && cc < img.cols)
            soft[size_t(rr) * img.cols + cc] = 0;
        }
    }
  fat_fraction_map(lengths.data(), lsig.data(), soft.data(), img.rows, img.cols, sigma_px, phi,
                   phi_var, use.data());
  dual_energy_bone(basis.data(), thickness.data(), phi.data(), phi_var.data(), int(n), k,
                   bone.data(), sigma.data(), dv);
}

// v's robust spread over the fillet (`whole`: one bin) under the detection's round kernel;
// infinity when too few pixels.
double round_spread(const FilletImage& img, const std::vector<float>& v,
                    const std::vector<uint8_t>& use, const ThicknessBins& whole,
                    const InspectionParams& p) {
  std::vector<float> smoothed;
  masked_gaussian(v.data(), use.data(), img.rows, img.cols, p.smooth_sigma_px, smoothed);
  const SpreadProfile sp = spread_profile(smoothed, whole, 0);
  return sp.scale.empty() ? std::numeric_limits<double>::infinity() : sp.scale[0];
}

// laser_and_low_line: z <- z / s + z1 / s1 where both are usable, s and s1 each z's robust
// spread over the fillet under the detection's round kernel (the counts' noise and the
// meat's clutter at the scale a fragment is seen at), z1 the low line's one-energy z. The
// detection brings the sum to unit spread again; a fragment that stands out in both
// stands out further, as far as the two images' clutter is not the same.
void add_one_energy(const FilletImage& img, const InspectionParams& p, const OneEnergyModel& one,
                    std::vector<uint8_t>& use, std::vector<float>& z) {
  const size_t n = img.size();
  for (size_t i = 0; i < n; ++i) use[i] = use[i] && one.use[i] && std::isfinite(one.z[i]);
  const ThicknessBins whole = thickness_bins(img.thickness.data(), use.data(), n, 1);
  const double s = round_spread(img, z, use, whole, p),
               s1 = round_spread(img, one.z, use, whole, p);
  // Too few pixels: the detection's own checks decide.
  if (!(s > 0 && s1 > 0 && std::isfinite(s) && std::isfinite(s1))) return;
  for (size_t i = 0; i < n; ++i) z[i] = use[i] ? float(z[i] / s + one.z[i] / s1) : kNaN;
}

}  // namespace

bool dual_energy_slopes(const FilletImage& img, size_t i, double lean[2], double bone[2]) {
  double open_lo = 0, open_hi = 0;
  open_beam(img, &open_lo, &open_hi);
  if (!(open_lo > 0 && open_hi > 0) || img.xray_high.size() != img.size() || !img.xray[i] ||
      !img.xray_high[i])
    return false;
  const DualEnergyParams& k = img.dual_energy;
  double a, b, j[4];
  if (!dual_energy_invert(k, std::log(open_lo / img.xray[i]), std::log(open_hi / img.xray_high[i]),
                          &a, &b, j))
    return false;
  double lu, lv, hu, hv;
  dual_energy_gradient(k.low, a / DE_A_MM, b / DE_B_MM, &lu, &lv);
  dual_energy_gradient(k.high, a / DE_A_MM, b / DE_B_MM, &hu, &hv);
  // d(x, y) / d(length): the gradient in (A, B) along the material's basis lengths.
  for (int m = 0; m < 2; ++m) {
    const double da = k.basis[m == 0 ? 0 : 4] / DE_A_MM, db = k.basis[m == 0 ? 1 : 5] / DE_B_MM;
    double* out = m == 0 ? lean : bone;
    out[0] = lu * da + lv * db;
    out[1] = hu * da + hv * db;
  }
  return lean[0] > 0 && lean[1] > 0 && bone[0] > lean[0] && bone[1] > lean[1];
}

namespace {

// After the fail-safe checks: into res, or res.reason.
void inspect_dual_energy(const FilletImage& img, const InspectionParams& p, bool keep,
                         FilletResult& res) {
  if (img.xray_high.size() != img.size()) {
    res.reason = "dual energy: the high-energy line is missing";
    return;
  }
  const auto t0 = std::chrono::steady_clock::now();
  double open_lo = 0, open_hi = 0;
  open_beam(img, &open_lo, &open_hi);
  if (!(open_lo > 0 && open_hi > 0)) {
    res.reason = "dual energy: too little bare belt beside the fillet to read the open beam";
    return;
  }
  const size_t n = img.size();
  // The thickness as the detector sees it (its blur and registration, measured: pipeline/
  // detector_match.h), over the low layer's transmission with this fillet's attenuation
  // per mm, as one energy does before its fit.
  std::vector<float> thickness = img.thickness;
  if (img.matches_detector()) {
    std::vector<double> mu;
    for (size_t i = 0; i < n; ++i)
      if (img.mask[i] && img.thickness[i] > 5 && img.xray[i] > 0)
        mu.push_back(std::log(open_lo / img.xray[i]) / img.thickness[i]);
    if (!mu.empty()) {
      FilletImage matched = img;
      match_detector(matched, std::clamp(median_inplace(mu.data(), mu.size()), 0.005, 0.3));
      thickness = std::move(matched.thickness);
    }
  }
  std::vector<uint8_t> use(n);
  for (size_t i = 0; i < n; ++i)
    use[i] = img.mask[i] && std::isfinite(thickness[i]) && img.xray[i] > 0 && img.xray_high[i] > 0;
  const std::vector<float> o_lo(n, float(open_lo)), o_hi(n, float(open_hi));
  DualEnergyBatch b;
  b.low = img.xray.data(), b.high = img.xray_high.data();
  b.open_low = o_lo.data(), b.open_high = o_hi.data();
  b.thickness = thickness.data(), b.use = use.data(), b.pixels = int(n);
  const DualEnergyParams& k = img.dual_energy;
  std::vector<float> basis(5 * n);
  dual_energy_basis(b, k, basis.data());
  // A pixel Newton's method could not take back (outside the wedge) takes no part.
  int outside = 0;
  for (size_t i = 0; i < n; ++i)
    if (use[i] && !std::isfinite(basis[5 * i])) use[i] = 0, ++outside;
  std::vector<float> bone, sigma, phi, phi_var;
  if (p.dual_energy == DualEnergyMethod::kNoLaser) {
    bone_without_laser(basis, use, k, bone, sigma);
  } else {
    std::vector<float> lengths(3 * n), lsig(3 * n);
    dual_energy_lengths(basis.data(), thickness.data(), int(n), k, lengths.data(), lsig.data());
    // The fat share's smoothing trades its noise against following the fat where it varies:
    // each fillet takes the scale (the finest, twice and four times it) whose bone image, as
    // the detection smooths it, spreads least (robustly: a fragment is a few pixels of it).
    // The spread is the robust one every statistic is brought to (thickness_spread.h), over
    // the whole fillet, after the round kernel (which shrinks the counts' noise, not what the
    // fat share's error paints).
    const std::vector<uint8_t> dense = denser_than_lean(img, lengths, lsig, use);
    const LaserBone in{img, basis, thickness, lengths, lsig, use, dense, k, p};
    const ThicknessBins whole = thickness_bins(thickness.data(), use.data(), n, 1);
    double best = 0;
    for (int s = 0; s < std::max(1, p.fat_share_scales); ++s) {
      std::vector<float> b_s, sg_s, phi_s, pv_s;
      bone_with_laser(in, p.fat_share_sigma_px * double(1 << s), b_s, sg_s, phi_s, pv_s);
      const double spread = round_spread(img, b_s, use, whole, p);
      if (s > 0 && !(spread < best)) continue;
      best = spread;
      bone = std::move(b_s), sigma = std::move(sg_s), phi = std::move(phi_s);
      phi_var = std::move(pv_s);
    }
  }
  std::vector<float> z(n, kNaN), resid(n, kNaN);
  int count = 0;
  double sum = 0, sum2 = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!use[i] || !std::isfinite(bone[i]) || !(sigma[i] > 0)) {
      use[i] = 0;
      continue;
    }
    resid[i] = -bone[i];
    z[i] = -bone[i] / sigma[i];
    sum += bone[i], sum2 += double(bone[i]) * bone[i], ++count;
  }
  if (count < 100 || outside > p.max_invalid_fraction * (count + outside)) {
    res.reason = "dual energy: " + std::to_string(outside) + " of the fillet's " +
                 std::to_string(count + outside) + " pixels lie outside what the wedge calibrated";
    return;
  }
  if (p.dual_energy == DualEnergyMethod::kLaserAndLowLine) {
    FilletResult low;  // the low line's fit, noise model and times (the checks passed above)
    OneEnergyModel one;
    if (!one_energy_model(img, p, low, one)) {
      res.reason = "dual energy with the low line: " + low.reason;
      return;
    }
    for (int s = 0; s < kStages; ++s) res.stage_seconds[s] += low.stage_seconds[s];
    add_one_energy(img, p, one, use, z);
  }
  // The residual statistics in the bone image's terms (mm of bone-equivalent).
  res.pixels = count;
  res.resid_mean_dn = sum / count;
  res.resid_std_dn = std::sqrt(std::max(0.0, sum2 / count - res.resid_mean_dn * res.resid_mean_dn));
  res.stage_seconds[kStageFit] +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  res.dual_energy = true;
  detect_from_z(img, use, z, {}, resid, nullptr, p, keep, res);
  for (Blob& f : res.fragments) f.bone_mg = kBoneMgPerMm3 * f.attenuation_mm2;
  if (keep) {
    res.bone_mm.assign(n, kNaN);
    for (size_t i = 0; i < n; ++i)
      if (use[i]) res.bone_mm[i] = bone[i];
    res.fat_share = std::move(phi);
  }
}

}  // namespace

FilletResult inspect_fillet_dual_energy(const FilletImage& img, const InspectionParams& p,
                                        bool keep) {
  return inspect_searchable(img, p, [&](const InspectionParams& q, FilletResult& res) {
    inspect_dual_energy(img, q, keep, res);
  });
}

}  // namespace rangex
