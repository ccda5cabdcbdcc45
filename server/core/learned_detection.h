// Detection thresholds learned from a plant's own clean product: for each
// detection statistic (round kernel, needle kernels, air pockets) a GEV model of its
// per-fillet extreme in thickness bands, and the threshold per band that meets the lane's
// per-fillet false-reject budget with a stated confidence. Empty (no bands): the fixed
// z thresholds of InspectionParams apply.
#pragma once
#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include "core/gev_model.h"

namespace rangex {

enum DetectionStatistic { kStatRound, kStatNeedle, kStatAir, kStatistics };
const char* statistic_name(int stat);  // "round", "needle", "air"
// The statistic statistic_name names; throws Error naming what it got otherwise.
int parse_statistic(const std::string& name);

// The thickness bands (mm of X-ray path) in which extremes are taken when nothing was learned.
const std::vector<double>& default_band_edges_mm();

struct LearnedStatistic {
  GevModel model;
  // A model fitted to the tail (pipeline/gev_fit.h): tail_from > 0, and each extreme at or
  // below whole_model's tail_from quantile counted only as lying there. The drift monitor
  // censors a lane's extremes at the same level. 0 in settings learned before: every extreme.
  double tail_from = 0;
  GevModel whole_model;
  std::vector<double> thresholds;         // per band: the statistic above it is a detection
  std::vector<double> band_fraction;      // of the learning fillets that held the band
  std::vector<double> band_pixels;        // their median pixel count in the band
  std::vector<double> band_thickness_mm;  // and median thickness there
};

// Round kernels whitened by the product's own texture (pipeline/matched_kernels.h): where
// present, the round statistic is the most bone-like of their outputs instead of the
// Gaussian's. Each kernel is C^-1 s over a (2 radius + 1)^2 window: s a calcified sphere's
// profile of sizes_mm[k], C the covariance of the learning fillets' z.
struct MatchedKernels {
  std::vector<double> sizes_mm;
  // Per size: its window's radius (the smallest, at least the bank's base of 4 px, that holds
  // the sphere: a large fragment seen through a small window shows only its rim) and its taps,
  // row-major over (2 radius + 1)^2.
  std::vector<int> radii;
  std::vector<std::vector<double>> taps;
  // Each kernel's output spread on the learned texture (z of unit robust spread): sqrt(h' C
  // h). A fillet's spread is measured, never below half of it (as the Gaussian's never
  // below its white-noise gain, which a whitened kernel's spread undercuts).
  std::vector<double> spreads;
  // z above its median by more than this many robust spreads is clipped before the kernels:
  // a bright speck (fat, air) seen by a kernel's negative flank would look like bone.
  double clip = 3;
  // And before the clip, each pixel less how far the bright level enclosing it within this
  // many px stands above the clip (pipeline/bright_enclosure.h; 0: the clip alone).
  int enclosure_px = 0;
  // z above its median by more than this many robust spreads is no texture of the product
  // but a void (an air pocket): it and its neighbours are set to the median before the
  // kernels, as meat of no texture, so that its rim does not read as bone to a kernel's
  // negative flank. Learned from the product's own brightest texture; 0: none.
  double void_level = 0;
  // Needle kernels, whitened by the same texture: a needle (a cylinder) of each diameter and
  // length along each direction (angle from across the belt toward along it), one kernel
  // each; the needle statistic takes the most bone-like. None: the elongated Gaussians.
  std::vector<double> needle_diameters_mm, needle_lengths_mm, needle_angles_deg;  // per kernel
  std::vector<int> needle_radii;
  std::vector<std::vector<double>> needle_taps;
  std::vector<double> needle_spreads;
  bool empty() const { return taps.empty(); }
  bool has_needles() const { return !needle_taps.empty(); }
  bool operator==(const MatchedKernels&) const = default;
  // The round kernels alone: the needle statistic back to the elongated Gaussians.
  void drop_needles() {
    needle_diameters_mm.clear(), needle_lengths_mm.clear(), needle_angles_deg.clear(),
        needle_radii.clear();
    needle_taps.clear(), needle_spreads.clear();
  }
  // The largest window's radius; the covariance was measured to twice it.
  int radius() const {
    int r = 0;
    for (int x : radii) r = std::max(r, x);
    for (int x : needle_radii) r = std::max(r, x);
    return r;
  }
};

// Learned thresholds lie within (0, kMaxLearnedThreshold) (plant.yaml refuses others). A
// model whose tail is too heavy for its extremes (a handful of fillets) would set thresholds
// beyond any statistic; learning holds them at the limit and fails.
constexpr double kMaxLearnedThreshold = 1e6;

struct LearnedDetection {
  std::string version;        // e.g. "learn-20261125-1" (rangexctl learn names it)
  std::string learned_on;     // the learning run: recording or live lane
  double target_frr = 0.003;  // per-fillet false-reject budget it was learned for
  double confidence = 0.9;    // the thresholds meet the budget with this confidence
  int fillets = 0;            // clean fillets it was learned from
  // The statistics' spread it was learned with (inspection.spread); inspection follows it.
  bool spread_by_thickness = false;
  // Whether the outline's wall was carried (inspection.rim_walls) when it was learned;
  // inspection follows it. Settings learned before 2026-12-01 carried none.
  bool rim_walls = false;
  std::vector<double> band_edges_mm;  // bands [e0, e1), [e1, e2), ...; the last open-ended
  std::array<LearnedStatistic, kStatistics> stats;
  MatchedKernels matched;  // empty: the round statistic is the Gaussian's
  // What the thresholds buy, as the learning measured it ("2.0 mm calcified sphere at 95 %
  // up to 20 mm of meat"): shown beside the active version.
  std::vector<std::string> sensitivity;

  bool active() const { return band_edges_mm.size() >= 2; }
  int bands() const { return int(band_edges_mm.size()) - 1; }
  int band_of(double thickness_mm) const;  // clamped to the first and last band
  double threshold(int stat, double thickness_mm) const;
};

// Band index of `t` in `edges` (clamped), shared by learning and inspection.
int band_index(const std::vector<double>& edges, double t);

}  // namespace rangex
