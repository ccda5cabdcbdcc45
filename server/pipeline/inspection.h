// Per-fillet compensation, detection and decision (Laser Range Imaging ch. 7):
//   fit ln I = b0 + b1 T robustly, pseudo-X-ray P = exp(b0 + b1 T), residual r = ln I - ln P,
//   z = r / sigma(P) with the fillet's own noise model, light Gaussian smoothing, then
//   smoothed z below -z_threshold -> bone fragments (reject), above +air_z_threshold -> air
//   pockets (reported only). Fail-safe: missing lines, too much meat without thickness, a
//   fillet on the lane edge, a fit that did not converge or a calibration mismatch give
//   "not inspected", which is a reject (the first two still searched where the fillet has
//   thickness, a bone found there named).
// A dual-energy lane with its calibration inspects its bone image instead
// (docs/dual-energy.md): inspection.dual_energy picks how.
// The X-ray-only baseline runs the same noise model and detector with a smooth background
// of ln I in place of the thickness model, so the laser's gain is measured.
#pragma once
#include <string>
#include <string_view>
#include <vector>

#include "core/lane_config.h"
#include "pipeline/fillet_image.h"
#include "pipeline/noise_model.h"
#include "pipeline/robust_fit.h"

namespace rangex {

enum class Decision { kPass, kReject, kNotInspected };
std::string_view decision_name(Decision d);

struct Blob {
  double x_mm = 0, y_mm = 0;  // weighted centre: across the belt, belt position
  double area_mm2 = 0;
  double peak_z = 0;           // most extreme smoothed z (negative for bone)
  double attenuation_mm2 = 0;  // sum of -ln(I / P) * pixel area: excess attenuation x area
  // The excess attenuation at its strongest point, in mm of the fillet's own meat (its
  // fitted attenuation per mm there); magnitude, for bone and air alike; 0 without a fit.
  // Under the round and elongated Gaussians and, for bone a whitened kernel found, under
  // that kernel (its piece's excess through the centre): the larger.
  double meat_mm = 0;
  int pixels = 0;
  int row0 = 0, row1 = 0, col0 = 0, col1 = 0;  // bounding box in the fillet image
  // Dual energy: the fragment's bone-equivalent mass (its bone lengths over its area, as
  // cortical bone of 1.92 mg/mm3), mg; 0 at one energy.
  double bone_mg = 0;
};

// The inspection's stages, timed per fillet (benchmarks, latency statistics).
enum InspectStage {
  kStageFit,
  kStageMatch,
  kStageNoise,
  kStageSmooth,
  kStageComponents,
  kStageExtremes,
  kStages
};
const char* inspect_stage_name(int stage);

// One detection statistic's extreme over one thickness band of a fillet
// (component_extreme.h): what product learning fits and drift tracking follows.
struct BandExtreme {
  int stat = 0;  // DetectionStatistic
  int band = 0;  // of the learned bands, or default_band_edges_mm()
  double x = 0;  // the extreme
  double n = 0;  // usable pixels in the band
  double t = 0;  // their median thickness, mm
};
// A band holds an extreme when it has at least this many usable pixels.
constexpr int kMinBandPixels = 100;

struct FilletResult {
  int lane = 0;
  int64_t id = 0;
  int64_t first_line = 0, first_encoder = 0;
  int rows = 0, cols = 0, first_col = 0;
  double x0_mm = 0, y0_mm = 0;
  double pitch_mm = 0.4, step_mm = 0.4;
  Decision decision = Decision::kNotInspected;
  std::string reason;
  bool fitted = false;
  RobustFit fit;
  bool dual_energy = false;  // inspected on the bone image of both X-ray lines (no fit)
  NoiseModel noise;
  std::vector<Blob> fragments, air_pockets;
  int pixels = 0;            // fillet pixels used
  double resid_mean_dn = 0;  // mean of I - P
  double resid_std_dn = 0;   // standard deviation of I - P
  double z_spread = 0;       // robust spread of the smoothed z before normalisation (middle bin)
  std::vector<BandExtreme> extremes;
  double stage_seconds[kStages] = {};
  // Images over the fillet's box (kept on request): pseudo-X-ray (DN), residual ln I - ln P,
  // smoothed z; NaN off the fillet.
  std::vector<float> pseudo, residual, zs;
  // The round and needle statistics at unit spread (larger: more bone-like), as thresholded;
  // kept on request; NaN off the fillet.
  std::vector<float> round_stat, needle_stat;
  // Dual energy (kept on request): bone-equivalent length per pixel (mm) and the fat's share
  // of the soft tissue (0..1; with the laser only); NaN off the fillet.
  std::vector<float> bone_mm, fat_share;
};

// keep_images: fill pseudo / residual / zs (and round_stat / needle_stat where computed).
FilletResult inspect_fillet(const FilletImage& img, const InspectionParams& p, bool keep_images);
// inspect_fillet (no images kept) under each of several learned thresholds that share their
// statistics (kernels, spread, rim): the fillet's model and statistics are made once and each
// set decides on them, so result k equals inspect_fillet with p.learned = learned[k]. Sets
// that do not share them, and dual-energy fillets, are inspected one by one.
std::vector<FilletResult> inspect_fillet_each(const FilletImage& img, const InspectionParams& p,
                                              const std::vector<LearnedDetection>& learned);
FilletResult inspect_fillet_xray_only(const FilletImage& img, const InspectionParams& p,
                                      bool keep_images);

}  // namespace rangex
