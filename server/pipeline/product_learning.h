// Product learning: thresholds from a plant's own clean fillets. Each detection
// statistic's per-fillet extreme in each thickness band (FilletResult::extremes) is fitted
// with a GEV regression (gev_fit.h); the threshold per band is the model's quantile that
// spends the lane's per-fillet false-reject budget, raised to the `confidence` quantile of
// a bootstrap over the learning fillets (an empirical maximum of 40 fillets cannot promise
// 0.3 %, a fitted tail with its uncertainty can). A learning run whose fillets hold
// something the model cannot explain (bone) fails, naming them.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/learned_detection.h"
#include "pipeline/gev_fit.h"
#include "pipeline/inspection.h"

namespace rangex {

struct LearningFillet {
  int lane = 0;
  int64_t id = 0;
  double y0_mm = 0;  // belt position of its first row (to find it on the recording)
  std::vector<BandExtreme> extremes;
};

// The top a whole fit is checked against: the share of extremes expected above its quantile
// (LearnOptions::tail_alpha).
constexpr double kTopShare = 0.01;

struct LearnOptions {
  double target_frr = 0.003;  // per fillet, for the rejecting statistics together
  double confidence = 0.9;    // of the bootstrap: the thresholds meet the budget this sure
  int bootstrap = 100;
  // A rejecting statistic whose own top extremes the fit to all of them does not hold (more
  // of them above its 99 % quantile than chance gives at `tail_alpha`) is fitted again to its
  // upper tail: the extremes at or below the whole fit's `tail_from` quantile (at their own
  // pixels and thickness) counted only as lying there (GevFitOptions::tail_from). False
  // rejects live in the tail, and a product with a second population in it (cartilage in
  // some fillets) has a bulk that does not say where its tail goes. Where the whole fit
  // holds its top it stays: on a product without one, the tail fit's thresholds met the
  // target in fewer learning runs. tail_from 0: never, as learned before 2026-12-04.
  double tail_from = 0.5;
  double tail_alpha = 0.05;
  int min_fillets = 30;
  uint64_t seed = 1;
  std::vector<double> band_edges_mm = default_band_edges_mm();
  bool spread_by_thickness = false;  // how the fillets' statistics were normalised
  bool rim_walls = false;            // and whether they carried the outline's wall
  // A learning fillet is suspected of holding bone when its extreme is this improbable
  // under the model fitted without it, after a Bonferroni correction over every band
  // extreme tested.
  double outlier_alpha = 0.01;
  // Before that, a gross-error screen: an extreme this many robust deviations above the
  // other fillets' in its band (bone stands 30-100 above clean meat's 3-10).
  double gross_mads = 20;
  // Fillets (lane, id) that the learning named and an operator checked and found clean
  // (cartilage, say, which one energy takes for bone): kept in, never flagged. Their product
  // is the plant's, so the thresholds rise over them.
  std::vector<std::pair<int, int64_t>> checked_clean;
};

struct FlaggedFillet {
  int lane = 0;
  int64_t id = 0;
  double y0_mm = 0;
  int stat = 0, band = 0;
  double x = 0;               // its extreme
  double log10_survival = 0;  // of that extreme under the model fitted without it
  double robust_z = 0;        // or: robust deviations above the other fillets' (the screen)
};

struct QQPoint {
  double expected = 0, observed = 0;  // Gumbel reduced variates
};

struct StatisticLearning {
  int samples = 0;
  GevFit fit;
  std::vector<double> point_thresholds;  // the point model's, per band
  std::vector<double> thresholds;        // raised to the confidence level (the ones used)
  double budget = 0;                     // its share of the per-fillet false-reject target
  double implied_frr = 0;                // at `thresholds` under the point model
  std::vector<QQPoint> qq;               // the learning extremes against the fitted model
  double ks_d = 0, ks_p = 1;             // Kolmogorov-Smirnov of the probability transforms
  int ks_samples = 0;                    // of the extremes fitted (a tail fit: above the bulk)
  // The whole fit against the learning's own top: extremes above its 99 % quantile, and how
  // likely that many or more are by chance (a rejecting statistic's; -1: not checked).
  int top_above = -1;
  double top_p = 1;
};

struct ProductLearning {
  bool ok = false;
  std::vector<std::string> problems;  // why it cannot be activated (empty when ok)
  int fillets = 0;                    // clean fillets used
  std::vector<FlaggedFillet> flagged;
  std::vector<FlaggedFillet> kept;  // would have been flagged; checked clean (checked_clean)
  std::array<StatisticLearning, kStatistics> stats;
  LearnedDetection learned;  // version and learned_on are the caller's
};

ProductLearning learn_product(const std::vector<LearningFillet>& fillets, const LearnOptions& opt);

// The per-fillet false-reject rate of the rejecting statistics at `learned`'s thresholds
// under its models (estimate_drift passes the models refitted to a lane's recent fillets).
double implied_false_reject_rate(const LearnedDetection& learned);

// Drift: each statistic's model refitted to recent passed fillets' extremes in location,
// scale and shape (truncated at the thresholds they stayed below, and at the learned model's
// lowest thousandth, below which an extreme is left out; the covariates' slopes held), and
// the false-reject rate the refitted models imply at the learned thresholds. `shift`: how
// far the extremes moved with the learned scale and shape (the refit's own median is not
// pinned where its lower tail is cut away; its tail is).
struct DriftEstimate {
  int fillets = 0;
  std::array<double, kStatistics> shift{};
  std::array<GevModel, kStatistics> models{};
  double implied_frr = 0;
};
DriftEstimate estimate_drift(const LearnedDetection& learned,
                             const std::vector<std::vector<BandExtreme>>& recent);

}  // namespace rangex
