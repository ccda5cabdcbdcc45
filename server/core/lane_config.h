// Everything the pipeline needs to know about one lane: sensor sizes, the calibrated rig
// geometry and the processing thresholds.
#pragma once
#include <array>
#include <string>

#include "core/camera_model.h"
#include "core/fan_beam.h"
#include "core/laser_plane.h"
#include "core/learned_detection.h"
#include "core/sensor_sources.h"
#include "core/stripe_params.h"

namespace rangex {

struct LaneCamera {
  std::string name;
  CameraModel model;
  ScatterConstants scatter;
  // Where K1/K2 were fitted (calib scatter writes the recording); empty or "shipped ...":
  // never fitted on this rig (they depend on the meat and the rig).
  std::string scatter_fitted_on;
};

struct FusionParams {
  double grid_pitch_mm = 0.2;       // fused profile sample spacing across the belt
  double grid_x0_mm = -100.0;       // x of the first fused sample
  int grid_samples = 1001;          // covers x0 .. x0 + pitch * (n - 1)
  double agree_tol_mm = 1.0;        // both cameras valid and closer than this: averaged
  double max_gap_mm = 3.0;          // shorter gaps are interpolated, longer ones stay invalid
  double max_column_step_mm = 2.0;  // neighbouring columns further apart are not joined
};

// How a dual-energy lane with its calibration inspects (docs/dual-energy.md): the bone
// length from both lines and the laser's thickness (laser); from both lines alone, as a
// dual-energy machine does without a thickness (no_laser: a comparison); or its low line as
// a lane of one energy (low_line); or the laser's bone image and the low line's one-energy
// z together (laser_and_low_line: each at unit spread under the detection's round kernel,
// summed, so that what shows in both shows more than the clutter of either).
enum class DualEnergyMethod { kLaser, kNoLaser, kLowLine, kLaserAndLowLine };

// Fillet assembly, compensation and detection (Laser Range Imaging ch. 7).
struct InspectionParams {
  double floor_mm = 1.5;               // thickness above this is fillet
  double min_fillet_area_mm2 = 800;    // smaller regions are debris, counted not inspected
  int gap_lines = 3;                   // empty lines that close a run of fillets
  int max_segment_lines = 2500;        // longer runs are closed (and inspected) anyway
  double max_invalid_fraction = 0.02;  // of a fillet's pixels without thickness: fail-safe
  int max_wall_gap_px = 4;  // a steep wall's hidden rim up to this wide is closed, not failed
  // The fillet's outline is a wall that stands somewhere within its outermost pixels; their
  // thickness carries that as a closure's does (pipeline/wall_gaps.h, rim_steps). Without
  // it, a fold's flap standing 4 mm high at the outline, measured half a pixel short along
  // 7 rows, was a needle of z 9.6 (folds_lost_lines: 2 of 200 clean fillets rejected).
  bool rim_walls = true;
  // ln I against the thickness: 1, the dissertation's line; 2, a parabola, for a
  // polychromatic beam whose hardening bends ln I in thick meat (fitted per fillet).
  int attenuation_degree = 2;
  double tukey_c = 5.0;
  // statsmodels' 50 is too few: IRLS walks on for 100 and more on fatty, marbled fillets
  // (docs/inspection.md), and a fit that did not settle is not inspected.
  int max_iter = 150;
  double tol = 1e-8;
  double smooth_sigma_px = 1.0;
  // Elongated kernels for needles (0: off): along and across, pixels.
  double line_sigma_along_px = 3.0, line_sigma_across_px = 0.7;
  double z_threshold = 5.0;  // smoothed z below -threshold is bone (unless learned)
  // Each detection statistic's spread measured by thickness across the fillet (true,
  // `spread: thickness`), or one per fillet (false, `spread: fillet`, the default: with fixed
  // thresholds the thin rims' smaller spread turned edge artefacts into fragments, 7.0 %
  // false rejects against 0.8 % on the nominal plant; learned per-band thresholds carry the
  // thickness either way, and measured within a fragment of each other: docs/inspection.md).
  bool spread_by_thickness = false;
  // Each fillet's detection extremes per thickness band (FilletResult::extremes), for
  // product learning and drift; off only to time the inspection without them (bench).
  bool band_extremes = true;
  // The per-fillet false-reject budget product learning sets thresholds for.
  double false_reject_target = 0.003;
  // Product learning whitens the round kernel by the product's own texture, one kernel per
  // calcified sphere of these sizes (mm; `[]`: the round Gaussian of smooth_sigma_px stays).
  // On rough_meat it found 57 of 58 calcified fragments >= 2 mm where the Gaussian found 53
  // (docs/inspection.md).
  std::vector<double> matched_kernels_mm = {1.5, 2.0, 3.0};
  // Before those kernels, z above its median by more than this many robust spreads is clipped,
  // in learning and inspection alike: a kernel's negative flank reads a bright speck (fat,
  // marbling) beside lean meat as bone. Bone lies on the other side and keeps its signal. At
  // 1.5 instead of 3, rough_meat and marbled_fat found 25 of 28 fragments >= 2 mm where 3
  // found 22, each rejecting 0 of 338 clean fillets; at 0.5 instead of 1.5, 164 of 174 where
  // 1.5 found 159, each rejecting 0 of 147 (docs/inspection.md). A clean run of 150 more
  // showed what 147 could not: marbled_fat rejected 2 at 0.5 and none at 1.5.
  double matched_clip = 0.5;
  // And before the clip, each pixel less how far the bright level that encloses it on every
  // line through it, within the largest kernel's window, stands above the clip
  // (pipeline/bright_enclosure.h): a fragment inside a fat streak keeps its depth below the
  // streak, where the clip alone cuts both to one value. Lean meat beside a streak or between
  // streaks along the muscle is not enclosed and stays as it was. On marbled_fat it found the
  // fragment in a streak (13 of 14 >= 2 mm, 12 without), rejecting 0 of 338 clean fillets;
  // rough_meat, needles, cartilage_heavy and nominal found and rejected what they did
  // without it (docs/inspection.md). Settings learned without it keep the clip alone.
  bool matched_enclosure = true;
  // A void's level, learned: this many times the learning fillets' median of their brightest
  // thousandth (99.9th percentile of z, in robust spreads). An air pocket removes meat
  // itself and stands far beyond any texture of the product; clipped to the texture's level
  // over its whole area, it is a bright plateau whose rim the whitened kernels read as bone
  // (the nominal plant's rare false detections, docs/inspection.md). 0: no voids.
  double matched_void_factor = 2.0;
  // And the needle statistic: kernels whitened by the same texture, matched to a needle of
  // each of these diameters and lengths (mm) along 8 directions (`[]`: the elongated
  // Gaussians of line_sigma_*_px stay). On rough meat the 2 mm kernel has 2.4-4.2x the
  // signal-to-noise of the elongated Gaussian on a 1.5-5 mm needle along it (docs/inspection.md).
  // A second, wider diameter matches fragments that lie flat (`matched_needle_diameter_mm`
  // takes a number or a list).
  std::vector<double> matched_needles_mm = {2.0};
  std::vector<double> matched_needle_diameters_mm = {0.6};
  // Thresholds learned from the plant's own clean product (rangexctl learn); when active
  // they replace z_threshold and air_z_threshold.
  LearnedDetection learned;
  double min_fragment_area_mm2 = 0.3;
  // A fragment must attenuate at its peak like this many mm of the fillet's own meat (0: off).
  // Cartilage and tendon stay under about 1.5 mm; so do needles and thin rib plates, which is
  // why it is off unless a plant's product has cartilage and no thin bone (docs/inspection.md).
  double min_fragment_meat_mm = 0;
  // A detection must add attenuation: one whose pixels, summed, attenuate no more than the
  // fillet's prediction (attenuation_mm2 <= 0) is no fragment. It drops a lean island that the
  // whitened kernels' bright enclosure reads by its depth below a ring of fat, and with it a
  // bone in fat lighter than lean meat over its pixels: on marbled_fat it dropped 3 of 6
  // detections of no bone and one calcified 2.5 mm fragment of 217. The plant's choice for
  // marbled product, off by default (docs/inspection.md). Learning and drift see the
  // statistics as before.
  bool require_added_attenuation = false;
  double air_z_threshold = 5.0;  // smoothed z above +threshold is an air pocket
  double min_air_area_mm2 = 1.0;
  double baseline_sigma_mm = 4.0;  // X-ray-only baseline: smooth background scale
  // An encoder jump further than this ends the lane's open fillets as not inspected and
  // restarts its assembly at the new count (a re-based PLC); shorter gaps are bridged.
  int encoder_horizon_lines = 100000;
  DualEnergyMethod dual_energy = DualEnergyMethod::kLaser;
  // Dual energy: the fat share's smoothing (pipeline/fat_fraction.h), px: the finest of
  // `fat_share_scales` (each twice the last), each fillet taking the one whose bone image
  // spreads least; and how much the soft tissue's density varies pixel to pixel (relative
  // sigma: cartilage, tendon, texture), which the bone's estimate discounts along the soft
  // tissue's direction.
  double fat_share_sigma_px = 12;
  int fat_share_scales = 3;
  double soft_density_sigma = 0.03;
};

struct LaneConfig {
  int id = 0;
  int frame_width = 640;
  int frame_height = 200;
  double encoder_step_mm = 0.4;
  std::array<LaneCamera, 2> cameras;
  LaserPlane laser;
  FanBeam xray;
  StripeParams stripe;
  int lut_step_px = 2;  // rectification table node spacing on the sensor
  FusionParams fusion;
  InspectionParams inspection;
  SensorSources sources;  // empty: fed over gRPC
};

// What a lane runs on that was never fitted or measured on its own rig (shipped K1/K2, an
// unmeasured detector blur, an unmeasured registration), as one warning line; empty when
// everything was.
std::string unfitted_constants(const LaneConfig& lane);

// The rig of the dissertation: cameras of appendices D and E, the second mirrored to the
// other side of the laser plane, both centred over the lane.
LaneConfig default_lane_config(int id);

}  // namespace rangex
