#include "pipeline/inspection.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>

#include "core/error.h"
#include "core/no_value.h"
#include "pipeline/closure_spread.h"
#include "pipeline/component_extreme.h"
#include "pipeline/connected_components.h"
#include "pipeline/detector_match.h"
#include "pipeline/inspection_steps.h"
#include "pipeline/masked_smooth.h"
#include "pipeline/matched_kernels.h"
#include "pipeline/thickness_spread.h"
#include "pipeline/wall_gaps.h"

namespace rangex {

std::string_view decision_name(Decision d) {
  switch (d) {
    case Decision::kPass:
      return "pass";
    case Decision::kReject:
      return "reject";
    default:
      return "not_inspected";
  }
}

const char* inspect_stage_name(int stage) {
  static const char* kNames[kStages] = {"fit",    "detector match", "noise model",
                                        "smooth", "components",     "band extremes"};
  return stage >= 0 && stage < kStages ? kNames[stage] : "?";
}

namespace {

FilletResult header(const FilletImage& img) {
  FilletResult r;
  r.lane = img.lane;
  r.id = img.id;
  r.first_line = img.first_line;
  r.first_encoder = img.first_encoder;
  r.rows = img.rows;
  r.cols = img.cols;
  r.first_col = img.first_col;
  r.x0_mm = img.x0_mm;
  r.y0_mm = img.y0_mm;
  r.pitch_mm = img.pitch_mm;
  r.step_mm = img.step_mm;
  return r;
}

// The fail-safe checks that need no fit; empty when the fillet can be inspected. searchable:
// what the fillet has is whole and true (its thickness where it has one, its lines), only not
// all of it: a bone found there is a bone.
std::string not_inspectable(const FilletImage& img, const InspectionParams& p, bool& searchable) {
  searchable = false;
  if (!img.interrupted.empty()) return img.interrupted;
  if (img.calibration_mismatch) return "calibration mismatch";
  if (img.missing_lines > 0) return std::to_string(img.missing_lines) + " lines missing";
  const int px = img.mask_pixels();
  searchable = px >= 100;
  if (img.touches_lane_edge) return "fillet reaches the edge of the lane";
  if (px < 100) return "too few fillet pixels (" + std::to_string(px) + ")";
  const double invalid = double(img.invalid_thickness_px) / double(px + img.invalid_thickness_px);
  if (invalid > p.max_invalid_fraction) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.1f%% of the fillet has no thickness", 100 * invalid);
    return buf;
  }
  return "";
}

// "2 bone fragments": a rejected fillet's reason.
std::string fragments_found(const FilletResult& r) {
  const size_t n = r.fragments.size();
  return std::to_string(n) + " bone fragment" + (n > 1 ? "s" : "");
}

}  // namespace

bool start_inspection(const FilletImage& img, const InspectionParams& p, FilletResult& res,
                      bool* searchable) {
  res = header(img);
  bool s = false;
  res.reason = not_inspectable(img, p, s);
  if (searchable) *searchable = s && !res.reason.empty();
  return res.reason.empty();
}

FilletResult inspect_searchable(
    const FilletImage& img, const InspectionParams& p,
    const std::function<void(const InspectionParams&, FilletResult&)>& inspect) {
  FilletResult res;
  bool searchable = false;
  if (start_inspection(img, p, res, &searchable)) {
    inspect(p, res);
    return res;
  }
  if (!searchable) return res;
  // Not inspected it stays; where what it has is whole (too much of it without thickness, or
  // off the lane's edge) it is still searched there, so that a bone in it is named: the plant
  // trims it rather than sending it round again.
  const std::string fail_safe = res.reason;
  InspectionParams q = p;
  q.band_extremes = false;  // not a passed fillet: learning and drift never see it
  inspect(q, res);
  res.decision = Decision::kNotInspected;
  res.reason = fail_safe;
  if (!res.fragments.empty()) res.reason += "; " + fragments_found(res) + " where it has thickness";
  return res;
}

namespace {

// Pixels that take part: on the fillet, with a thickness and an X-ray count.
std::vector<uint8_t> usable(const FilletImage& img) {
  std::vector<uint8_t> m(img.size());
  for (size_t i = 0; i < m.size(); ++i)
    m[i] = img.mask[i] && std::isfinite(img.thickness[i]) && img.xray[i] > 0;
  return m;
}

// The meat's own attenuation per mm at thickness t (the slope of the fit), or 0 without one.
double meat_mu(const RobustFit* fit, double t) {
  return fit ? -(fit->beta1 + 2 * fit->beta2 * t) : 0.0;
}

// The strongest excess attenuation sgn * -ln(I / P) at pixel (r, c) under the detection's
// own kernels (round, and elongated along four directions, so that a needle keeps its
// contrast), evaluated at that pixel only.
double local_excess(const std::vector<float>& resid, const std::vector<uint8_t>& use,
                    const FilletImage& img, int r, int c, double sgn, const InspectionParams& p) {
  // The smoothing is linear: the excess -ln(I / P) smoothed is the residual smoothed, negated.
  double best = -sgn * masked_smooth_at(resid.data(), use.data(), img.rows, img.cols,
                                        p.smooth_sigma_px, 0, -1, r, c);
  if (p.line_sigma_along_px > 0)
    for (int dir = 0; dir < 4; ++dir)
      best = std::max(
          best, -sgn * masked_smooth_at(resid.data(), use.data(), img.rows, img.cols,
                                        p.line_sigma_along_px, p.line_sigma_across_px, dir, r, c));
  return std::isfinite(best) ? best : 0.0;
}

// The excess attenuation at pixel (r, c) under the whitened kernel whose statistic is that
// pixel's, NaN where none is (matched_excess below).
using KernelExcess = std::function<double(int r, int c)>;

// Components of `on` of at least min_area_mm2; w: the statistic oriented so that larger is
// more bone-like (sign -1) or air-like (+1). With a fit, those whose contrast reads less
// than `min_meat_mm` of meat (a plant's floor; 0: none) are left out, and their pixels set
// in `dropped` when it is given.
std::vector<Blob> blobs(const std::vector<float>& w_map, const std::vector<uint8_t>& on,
                        const std::vector<float>& resid, const std::vector<uint8_t>& use,
                        const FilletImage& img, double sign, double min_area_mm2,
                        const RobustFit* fit, const InspectionParams& p,
                        const KernelExcess& kernel_excess = {}, double min_meat_mm = 0,
                        std::vector<uint8_t>* dropped = nullptr) {
  const double px_area = img.pitch_mm * img.step_mm;
  std::vector<int> labels;
  const auto comps = label_components(on.data(), img.rows, img.cols, labels);
  std::vector<Blob> out;
  struct Strong {
    double w;
    int r, k;
  };
  std::vector<Strong> strongest;
  for (const Component& c : comps) {
    if (c.pixels * px_area < min_area_mm2) continue;
    Blob b;
    b.pixels = c.pixels;
    b.area_mm2 = c.pixels * px_area;
    b.row0 = c.row0;
    b.row1 = c.row1;
    b.col0 = c.col0;
    b.col1 = c.col1;
    double wsum = 0, wx = 0, wy = 0, peak = 0;
    size_t peak_i = 0;
    for (int r = c.row0; r <= c.row1; ++r)
      for (int k = c.col0; k <= c.col1; ++k) {
        const size_t i = size_t(r) * img.cols + k;
        if (labels[i] != c.label) continue;
        const double w = w_map[i];
        wsum += w;
        wx += w * k;
        wy += w * r;
        if (w > peak) peak = w, peak_i = i;
        b.attenuation_mm2 += -double(resid[i]) * px_area;  // > 0 for bone, < 0 for air
        strongest.push_back({w, r, k});
      }
    // Where the plant asks: bone adds attenuation over its pixels. A component that adds none
    // is a lean island the bright enclosure read by its depth below fat, or a bone in fat
    // lighter than lean meat, which this drops too (lane_config.h).
    if (sign < 0 && p.require_added_attenuation && !(b.attenuation_mm2 > 0)) {
      strongest.clear();
      continue;
    }
    // Its contrast where its statistic is strongest (the few best pixels: each evaluation
    // runs the five kernels). Under the Gaussians and, where a whitened kernel found the
    // pixel, under that kernel too, the larger: a Gaussian smooths a small piece away and
    // reads the meat around it (nothing in a fat lump), a small kernel sees only part of a
    // large piece.
    const size_t best = std::min<size_t>(8, strongest.size());
    std::partial_sort(strongest.begin(), strongest.begin() + long(best), strongest.end(),
                      [](const auto& a, const auto& b) { return a.w > b.w; });
    for (size_t q = 0; q < best; ++q) {
      const auto [w, r, k] = strongest[q];
      const double mu = meat_mu(fit, img.thickness[size_t(r) * img.cols + k]);
      if (!(mu > 0)) continue;
      double excess = local_excess(resid, use, img, r, k, -sign, p);
      if (kernel_excess) {
        const double e = kernel_excess(r, k);
        if (std::isfinite(e)) excess = std::max(excess, e);
      }
      b.meat_mm = std::max(b.meat_mm, excess / mu);
    }
    strongest.clear();
    if (fit && min_meat_mm > 0 && b.meat_mm < min_meat_mm) {
      if (dropped) {
        dropped->resize(img.size(), 0);
        for (int r = c.row0; r <= c.row1; ++r)
          for (int k = c.col0; k <= c.col1; ++k) {
            const size_t i = size_t(r) * img.cols + k;
            if (labels[i] == c.label) (*dropped)[i] = 1;
          }
      }
      continue;
    }
    // The detector sees the fragment magnified by the fan beam; put it back at mid-depth of
    // the meat above it (the path thickness there is close to the vertical thickness).
    const double x_det = img.x0_mm + img.pitch_mm * (wx / wsum);
    const double t = std::isfinite(img.thickness[peak_i]) ? img.thickness[peak_i] : 0.0;
    b.x_mm = img.source_x_mm + (x_det - img.source_x_mm) * (img.source_z_mm - 0.5 * t) /
                                   (img.source_z_mm - img.detector_z_mm);
    b.y_mm = img.y0_mm + img.step_mm * (wy / wsum);
    b.peak_z = sign * peak;
    out.push_back(b);
  }
  std::sort(out.begin(), out.end(),
            [](const Blob& a, const Blob& b) { return std::abs(a.peak_z) > std::abs(b.peak_z); });
  return out;
}

// Adds the time since the previous lap to a stage.
class StageLap {
 public:
  explicit StageLap(FilletResult& r) : r_(r), t_(std::chrono::steady_clock::now()) {}
  void operator()(int stage) {
    const auto now = std::chrono::steady_clock::now();
    r_.stage_seconds[stage] += std::chrono::duration<double>(now - t_).count();
    t_ = now;
  }

 private:
  FilletResult& r_;
  std::chrono::steady_clock::time_point t_;
};

// Each statistic's extreme per thickness band (component_extreme.h): what product learning
// fits and drift tracking follows.
// floored: pixels of fragments the plant's floor dropped (or empty), left out of the bone
// statistics' extremes.
void band_extremes(const FilletImage& img, const std::vector<uint8_t>& use,
                   const std::vector<float> (&stat)[kStatistics], const InspectionParams& p,
                   const std::vector<uint8_t>& floored, FilletResult& res) {
  const size_t n = img.size();
  const std::vector<double>& edges =
      p.learned.active() ? p.learned.band_edges_mm : default_band_edges_mm();
  const double px_area = img.pitch_mm * img.step_mm;
  // Each usable pixel's band, gathered once; every statistic runs over the same lists.
  const int bands = int(edges.size()) - 1;
  std::vector<std::vector<size_t>> members(size_t(std::max(0, bands)));
  for (size_t i = 0; i < n; ++i)
    if (use[i]) members[size_t(band_index(edges, img.thickness[i]))].push_back(i);
  std::vector<size_t> px;
  std::vector<double> ts;
  for (int band = 0; band < bands; ++band) {
    const std::vector<size_t>& in = members[size_t(band)];
    const int count = int(in.size());
    if (count < kMinBandPixels) continue;
    ts.clear();
    for (size_t i : in) ts.push_back(img.thickness[i]);
    const double t_mid = median_inplace(ts.data(), ts.size());
    for (int s = 0; s < kStatistics; ++s) {
      if (s == kStatNeedle && p.line_sigma_along_px <= 0) continue;
      const double area = s == kStatAir ? p.min_air_area_mm2 : p.min_fragment_area_mm2;
      const int min_px = std::max(1, int(std::ceil(area / px_area - 1e-9)));
      px = in;
      if (s != kStatAir && !floored.empty())
        std::erase_if(px, [&](size_t i) { return floored[i] != 0; });
      const double x = component_extreme(stat[s].data(), px, img.rows, img.cols, min_px);
      if (std::isfinite(x)) res.extremes.push_back({s, band, x, double(count), t_mid});
    }
  }
}

// From the model of ln I to z: the residual, the noise model (into res) and z, with the
// prediction P (DN) per pixel. closure_var: what the closures of gaps in the thickness add
// to var(ln P) per pixel (wall_gaps.h), or empty; closure_z: their spread in z's units per
// pixel (closure_spread.h), empty when there are none.
void one_energy_z(const FilletImage& img, const std::vector<uint8_t>& use,
                  const std::vector<float>& predicted_ln, const std::vector<float>& closure_var,
                  FilletResult& res, std::vector<float>& z, std::vector<float>& resid,
                  std::vector<float>& pred, std::vector<float>& closure_z) {
  StageLap lap(res);
  const size_t n = img.size();
  pred.assign(n, kNaN), resid.assign(n, kNaN);
  double sum = 0, sum2 = 0;
  int count = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!use[i]) continue;
    pred[i] = std::exp(predicted_ln[i]);
    resid[i] = float(std::log(double(img.xray[i])) - predicted_ln[i]);
    const double d = double(img.xray[i]) - pred[i];
    sum += d;
    sum2 += d * d;
    ++count;
  }
  res.pixels = count;
  res.resid_mean_dn = sum / count;
  res.resid_std_dn = std::sqrt(std::max(0.0, sum2 / count - res.resid_mean_dn * res.resid_mean_dn));
  res.noise = estimate_noise_model(pred.data(), resid.data(), n);
  // Squared gradient of ln P (per pixel) by central differences inside the usable pixels.
  std::vector<float> grad2(n, kNaN);
  const int R = img.rows, C = img.cols;
  // Central where both neighbours are usable, one-sided at the mask's border.
  auto slope = [&](size_t i, size_t lo, size_t hi, bool has_lo, bool has_hi) {
    const bool a = has_lo && use[lo], b = has_hi && use[hi];
    if (a && b) return 0.5 * (double(predicted_ln[hi]) - predicted_ln[lo]);
    if (b) return double(predicted_ln[hi]) - predicted_ln[i];
    if (a) return double(predicted_ln[i]) - predicted_ln[lo];
    return 0.0;
  };
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < C; ++c) {
      const size_t i = size_t(r) * C + c;
      if (!use[i]) continue;
      const double gx = slope(i, i - 1, i + 1, c > 0, c + 1 < C);
      const double gy = slope(i, i - C, i + C, r > 0, r + 1 < R);
      grad2[i] = float(gx * gx + gy * gy);
    }
  const bool closures = closure_var.size() == n;
  // A closed pixel's residual is the closure's, not the registration's: not fitted.
  std::vector<float> fitted;
  if (closures) {
    fitted = grad2;
    for (size_t i = 0; i < n; ++i)
      if (closure_var[i] > 0) fitted[i] = kNaN;
  }
  res.noise.c = estimate_gradient_term(res.noise, pred.data(), resid.data(),
                                       (closures ? fitted : grad2).data(), n);
  z.assign(n, kNaN);
  closure_z.assign(closures ? n : 0, 0.0f);
  for (size_t i = 0; i < n; ++i) {
    if (!use[i]) continue;
    const double s = res.noise.sigma_ln(pred[i], grad2[i]);
    const double v = closures ? closure_var[i] : 0.0;
    z[i] = float(resid[i] / std::sqrt(s * s + v));
    if (v > 0) closure_z[i] = float(std::sqrt(v / (s * s + v)));
  }
  lap(kStageNoise);
}

// Everything after the model of ln I: noise model, z, detection, decision, statistics.
void detect_and_decide(const FilletImage& img, const std::vector<uint8_t>& use,
                       const std::vector<float>& predicted_ln, const RobustFit* fit,
                       const InspectionParams& p, bool keep, FilletResult& res) {
  std::vector<float> z, resid, pred, closure_z;
  one_energy_z(img, use, predicted_ln, {}, res, z, resid, pred, closure_z);
  detect_from_z(img, use, z, closure_z, resid, fit, p, keep, res);
  if (keep) res.pseudo = std::move(pred);
}

}  // namespace

void statistics_from_z(const FilletImage& img, const std::vector<uint8_t>& use,
                       const std::vector<float>& z, const std::vector<float>& closure_z,
                       const InspectionParams& p, FilletResult& res, DetectionStatistics& ds) {
  StageLap lap(res);
  const size_t n = img.size();
  std::vector<float> zs;
  // Each statistic is brought to unit spread where it is computed: after its kernel, by
  // thickness, robustly (thickness_spread.h). What compensation leaves is not white (meat
  // texture, thickness error), smoothing shrinks white noise far more than that, and thick
  // meat is rougher than thin; the white-noise factor is the floor.
  // One bin is the whole fillet: one spread per fillet (inspection.spread: fillet).
  // Learned thresholds hold for the spread they were learned with.
  const bool by_thickness =
      p.learned.active() ? p.learned.spread_by_thickness : p.spread_by_thickness;
  const ThicknessBins bins =
      thickness_bins(img.thickness.data(), use.data(), n, by_thickness ? 8 : 1);
  const MatchedKernels& mk = p.learned.matched;
  // Where gaps were closed, each statistic carries the closure's error as its kernel sums it
  // (closure_spread.h): reach is the widest kernel's half-width.
  int reach = smooth_reach_px(p.smooth_sigma_px);
  for (int r : mk.radii) reach = std::max(reach, r);
  for (int r : mk.needle_radii) reach = std::max(reach, r);
  if (!mk.has_needles() && p.line_sigma_along_px > 0)
    reach = std::max(reach, smooth_reach_px(p.line_sigma_along_px, p.line_sigma_across_px));
  const ClosureReach cr = closure_reach(closure_z, use.data(), img.rows, img.cols, reach);
  // A Gaussian's share of the closures is their e smoothed by the same masked kernel, taken
  // over the whole image at once and read at the pixels near them.
  std::vector<float> e_smoothed;
  auto near_values = [&]() {
    std::vector<double> sums(cr.near.size());
    for (size_t k = 0; k < cr.near.size(); ++k) sums[k] = e_smoothed[cr.near[k]];
    return sums;
  };
  masked_gaussian(z.data(), use.data(), img.rows, img.cols, p.smooth_sigma_px, zs);
  const SpreadProfile round_spread = unit_spread_by_thickness(
      zs, img.thickness.data(), use.data(), bins, gaussian_noise_gain(p.smooth_sigma_px));
  if (!cr.empty()) {
    masked_gaussian(cr.e.data(), use.data(), img.rows, img.cols, p.smooth_sigma_px, e_smoothed);
    discount_closures(zs, cr, img.thickness.data(), round_spread, near_values());
  }
  res.z_spread =
      round_spread.scale.empty() ? 0.0 : round_spread.scale[round_spread.scale.size() / 2];
  // The statistics, oriented so that larger is more bone-like (round, needle) or air-like.
  std::vector<float>(&stat)[kStatistics] = ds.stat;
  stat[kStatRound].assign(n, kNaN);
  stat[kStatNeedle].assign(n, kNaN);
  stat[kStatAir] = zs;
  // Kernels whitened by the product's texture (matched_kernels.h), bright specks clipped
  // first; each brought to unit spread like the Gaussian, a pixel as bone-like as its most
  // bone-like kernel.
  // which[i]: the kernel whose statistic pixel i's is (a fragment's contrast is measured
  // under it).
  std::vector<float>& zc = ds.zc;
  std::vector<float> zk;
  std::vector<int16_t>&round_k = ds.round_k, &needle_k = ds.needle_k;
  round_k.assign(mk.empty() ? 0 : n, -1);
  needle_k.assign(mk.has_needles() ? n : 0, -1);
  PaddedField zp;  // zc padded once for every kernel
  if (!mk.empty() || mk.has_needles()) {
    clip_bright(z.data(), use.data(), img.rows, img.cols, mk.clip, mk.enclosure_px, mk.void_level,
                zc);
    int widest = 0;
    for (int r : mk.radii) widest = std::max(widest, r);
    for (int r : mk.needle_radii) widest = std::max(widest, r);
    zp = pad_field(zc.data(), use.data(), img.rows, img.cols, widest);
  }
  std::vector<double> abs_taps, closure_acc;
  auto most_bone_like = [&](const std::vector<double>& taps, int radius, double spread,
                            std::vector<float>& into, std::vector<int16_t>& which, size_t k) {
    apply_kernel(zp, use.data(), taps, radius, zk);
    const SpreadProfile s =
        unit_spread_by_thickness(zk, img.thickness.data(), use.data(), bins, 0.5 * spread);
    if (!cr.empty()) {
      abs_taps.resize(taps.size());
      for (size_t j = 0; j < taps.size(); ++j) abs_taps[j] = std::abs(taps[j]);
      if (closure_acc.empty()) closure_acc.assign(n, 0.0);
      discount_closures(zk, cr, img.thickness.data(), s,
                        closure_kernel_sums(cr, img.rows, img.cols, abs_taps, radius, closure_acc));
    }
    for (size_t i = 0; i < n; ++i)
      if (std::isfinite(zk[i]) && !(into[i] >= -zk[i])) into[i] = -zk[i], which[i] = int16_t(k);
  };
  if (mk.empty()) {
    for (size_t i = 0; i < n; ++i) stat[kStatRound][i] = -zs[i];
  } else {
    for (size_t k = 0; k < mk.taps.size(); ++k)
      most_bone_like(mk.taps[k], mk.radii[k], mk.spreads[k], stat[kStatRound], round_k, k);
  }
  // Needles and slivers: a pixel or less wide, they fade under the round kernel. Learned
  // needle kernels (one per length and direction) where the product taught them, else
  // elongated kernels along four directions, each brought to unit spread the same way. A
  // pixel is as needle-like as its most needle-like kernel.
  if (mk.has_needles()) {
    for (size_t k = 0; k < mk.needle_taps.size(); ++k)
      most_bone_like(mk.needle_taps[k], mk.needle_radii[k], mk.needle_spreads[k], stat[kStatNeedle],
                     needle_k, k);
  } else if (p.line_sigma_along_px > 0) {
    std::vector<float> zl;
    for (int dir = 0; dir < 4; ++dir) {
      const double gain =
          masked_line_gaussian(z.data(), use.data(), img.rows, img.cols, p.line_sigma_along_px,
                               p.line_sigma_across_px, dir, zl);
      const SpreadProfile s =
          unit_spread_by_thickness(zl, img.thickness.data(), use.data(), bins, gain);
      if (!cr.empty()) {
        masked_line_gaussian(cr.e.data(), use.data(), img.rows, img.cols, p.line_sigma_along_px,
                             p.line_sigma_across_px, dir, e_smoothed);
        discount_closures(zl, cr, img.thickness.data(), s, near_values());
      }
      for (size_t i = 0; i < n; ++i)
        if (std::isfinite(zl[i]) && !(stat[kStatNeedle][i] >= -zl[i]))
          stat[kStatNeedle][i] = -zl[i];
    }
  }
  lap(kStageSmooth);
}

void decide_from_statistics(const FilletImage& img, const std::vector<uint8_t>& use,
                            const std::vector<float>& z, std::vector<float>& resid,
                            const RobustFit* fit, DetectionStatistics& ds,
                            const InspectionParams& p, bool keep, FilletResult& res) {
  StageLap lap(res);
  const size_t n = img.size();
  const MatchedKernels& mk = p.learned.matched;
  std::vector<float>(&stat)[kStatistics] = ds.stat;
  const std::vector<float>& zc = ds.zc;
  const std::vector<int16_t>&round_k = ds.round_k, &needle_k = ds.needle_k;
  // Thresholds: learned from the plant's own product per thickness band, else the fixed ones.
  const LearnedDetection& L = p.learned;
  auto threshold = [&](int s, size_t i) {
    if (L.active()) return L.threshold(s, img.thickness[i]);
    return s == kStatAir ? p.air_z_threshold : p.z_threshold;
  };
  std::vector<uint8_t> bone_on(n, 0), air_on(n, 0);
  std::vector<float> bone_w(n, kNaN);
  for (size_t i = 0; i < n; ++i) {
    if (!use[i]) continue;
    const float r = stat[kStatRound][i], nd = stat[kStatNeedle][i];
    bone_on[i] =
        r > threshold(kStatRound, i) || (std::isfinite(nd) && nd > threshold(kStatNeedle, i));
    bone_w[i] = std::isfinite(nd) ? std::max(r, nd) : r;
    air_on[i] = stat[kStatAir][i] > threshold(kStatAir, i);
  }
  // A whitened kernel h has h . s = 1 for its piece's chord s (mm): on the residual it reads
  // the piece's excess attenuation per mm of chord, unbiased in that shape, and times the
  // piece's chord through its centre (the sphere's diameter, the needle's) the excess there.
  // It runs on the residual as the kernels saw it, bright values clipped (zc / z of them),
  // made once a fillet has a fragment.
  std::vector<float> resid_c;
  const KernelExcess matched_excess = [&](int r, int c) {
    const size_t i = size_t(r) * img.cols + c;
    const float rs = stat[kStatRound][i], nd = stat[kStatNeedle][i];
    const bool needle = std::isfinite(nd) && nd > rs;  // as bone_w below
    const std::vector<int16_t>& which = needle ? needle_k : round_k;
    const int k = which.empty() ? -1 : which[i];
    if (k < 0) return double(kNaN);
    if (resid_c.empty()) {
      resid_c = resid;
      for (size_t j = 0; j < n; ++j)
        if (use[j] && z[j] > zc[j] && z[j] != 0) resid_c[j] = resid[j] * (zc[j] / z[j]);
    }
    const size_t kk = size_t(k);
    const double a = apply_kernel_at(resid_c.data(), use.data(), img.rows, img.cols,
                                     needle ? mk.needle_taps[kk] : mk.taps[kk],
                                     needle ? mk.needle_radii[kk] : mk.radii[kk], r, c);
    return -a * (needle ? mk.needle_diameters_mm[kk] : mk.sizes_mm[kk]);
  };
  // What the plant's floor drops is no reject, so under learned thresholds its pixels are no
  // part of the extremes that drift follows either (learning fits those taken without them).
  std::vector<uint8_t> floored;
  res.fragments = blobs(bone_w, bone_on, resid, use, img, -1, p.min_fragment_area_mm2, fit, p,
                        matched_excess, p.min_fragment_meat_mm, L.active() ? &floored : nullptr);
  res.air_pockets = blobs(stat[kStatAir], air_on, resid, use, img, +1, p.min_air_area_mm2, fit, p);
  lap(kStageComponents);
  // Each statistic's extreme per thickness band: what product learning fits and drift
  // tracking follows.
  if (p.band_extremes) {
    band_extremes(img, use, stat, p, floored, res);
    lap(kStageExtremes);
  }
  if (res.fragments.empty()) {
    res.decision = Decision::kPass;
  } else {
    res.decision = Decision::kReject;
    res.reason = fragments_found(res);
  }
  if (keep) {
    res.residual = std::move(resid);
    res.zs = std::move(stat[kStatAir]);
    res.round_stat = std::move(stat[kStatRound]);
    res.needle_stat = std::move(stat[kStatNeedle]);
  }
}

void detect_from_z(const FilletImage& img, const std::vector<uint8_t>& use,
                   const std::vector<float>& z, const std::vector<float>& closure_z,
                   std::vector<float>& resid, const RobustFit* fit, const InspectionParams& p,
                   bool keep, FilletResult& res) {
  DetectionStatistics ds;
  statistics_from_z(img, use, z, closure_z, p, res, ds);
  decide_from_statistics(img, use, z, resid, fit, ds, p, keep, res);
}

bool one_energy_model(const FilletImage& raw, const InspectionParams& p, FilletResult& res,
                      OneEnergyModel& m) {
  // The fit of ln I against the thickness, over the usable pixels of `img`: the parabola
  // of a hardened beam (degree 2) where the fillet's thicknesses determine one, else the
  // line. A fillet of nearly one thickness (a plateau and its wall) leaves the parabola
  // undetermined or unsettled, and then the line stands.
  auto fit = [&](const FilletImage& img, std::vector<uint8_t>& use, int degree) {
    use = usable(img);
    std::vector<double> t, y;
    for (size_t i = 0; i < use.size(); ++i)
      if (use[i]) {
        t.push_back(img.thickness[i]);
        y.push_back(std::log(double(img.xray[i])));
      }
    const RobustFitOptions o{p.tukey_c, p.max_iter, p.tol};
    if (degree == 2) {
      try {
        const RobustFit bent = fit_tukey_poly(t.data(), y.data(), t.size(), 2, o);
        if (bent.converged) {
          res.fit = bent;
          res.fitted = true;
          return true;
        }
      } catch (const Error&) {
        // The line below.
      }
    }
    try {
      res.fit = fit_tukey_line(t.data(), y.data(), t.size(), o);
    } catch (const Error& e) {
      res.reason = std::string("robust fit failed: ") + e.what();
      return false;
    }
    res.fitted = true;
    if (!res.fit.converged) {
      res.reason =
          "robust fit did not converge in " + std::to_string(res.fit.iterations) + " iterations";
      return false;
    }
    return true;
  };
  StageLap lap(res);
  std::vector<uint8_t>& use = m.use;
  // Before a detector match the fit only gives the meat's attenuation: the line will do.
  if (!fit(raw, use, raw.matches_detector() ? 1 : p.attenuation_degree)) return false;
  lap(kStageFit);
  // With the lane's detector known, the thickness is made what the detector would see
  // (the meat's attenuation from this first fit), and fitted again.
  m.matched = raw.matches_detector();
  const FilletImage* img = &raw;
  if (m.matched) {
    m.matched_image = raw;
    match_detector(m.matched_image, std::clamp(-res.fit.beta1, 0.005, 0.3));
    img = &m.matched_image;
    lap(kStageMatch);
    if (!fit(m.matched_image, use, p.attenuation_degree)) return false;
    lap(kStageFit);
  }
  std::vector<float> predicted(img->size(), kNaN);
  for (size_t i = 0; i < use.size(); ++i)
    if (use[i]) {
      const double t = img->thickness[i];
      predicted[i] = float(res.fit.beta0 + t * (res.fit.beta1 + res.fit.beta2 * t));
    }
  const auto mu = [&](double t) { return meat_mu(&res.fit, t); };
  // Learned thresholds hold for the statistics they were learned with.
  const bool rim = p.learned.active() ? p.learned.rim_walls : p.rim_walls;
  one_energy_z(*img, use, predicted, closure_variance(*img, mu, rim), res, m.z, m.resid, m.pred,
               m.closure_z);
  return true;
}

bool inspected_in_dual_energy(const FilletImage& img, const InspectionParams& p) {
  return !img.xray_high.empty() && img.has_dual_energy &&
         p.dual_energy != DualEnergyMethod::kLowLine;
}

FilletResult inspect_fillet(const FilletImage& raw, const InspectionParams& p, bool keep) {
  if (inspected_in_dual_energy(raw, p)) return inspect_fillet_dual_energy(raw, p, keep);
  return inspect_searchable(raw, p, [&](const InspectionParams& q, FilletResult& res) {
    OneEnergyModel m;
    if (!one_energy_model(raw, q, res, m)) return;
    detect_from_z(m.image(raw), m.use, m.z, m.closure_z, m.resid, &res.fit, q, keep, res);
    if (keep) res.pseudo = std::move(m.pred);
  });
}

FilletResult inspect_fillet_xray_only(const FilletImage& img, const InspectionParams& lane,
                                      bool keep) {
  // Fixed thresholds and the round Gaussian: what a lane learns (its thresholds, its whitened
  // kernels) is learned on the laser's z, not on this background's.
  // A fail-safe fillet is searched as rangex searches it, so that the two compare alike.
  InspectionParams p = lane;
  p.learned = {};
  return inspect_searchable(img, p, [&](const InspectionParams& q, FilletResult& res) {
    const std::vector<uint8_t> use = usable(img);
    std::vector<float> ln(img.size(), kNaN), background;
    for (size_t i = 0; i < use.size(); ++i)
      if (use[i]) ln[i] = float(std::log(double(img.xray[i])));
    masked_gaussian(ln.data(), use.data(), img.rows, img.cols, q.baseline_sigma_mm / img.pitch_mm,
                    background);
    detect_and_decide(img, use, background, nullptr, q, keep, res);
  });
}

}  // namespace rangex
