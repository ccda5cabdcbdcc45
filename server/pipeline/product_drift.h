// Drift while running: a lane tracks the detection extremes of the fillets it
// passes against its active learned model. Every `every` fillets the last `window` are
// fitted for a location shift per statistic (product_learning.h: estimate_drift); the
// false-reject rate that shift implies is what statistics, /metrics and the dashboard show.
// Nothing changes a threshold by itself: a plant re-learns and activates, audited.
#pragma once
#include <deque>
#include <string>
#include <vector>

#include "pipeline/product_learning.h"

namespace rangex {

// What a lane shows of it: the rate implied (-1: not estimated yet), over how many passed
// fillets, and whether that is more than twice the target.
struct DriftShown {
  double implied_frr = -1;
  int fillets = 0;
  bool drifting = false;
};

// It says nothing until the window is full: the last 200 passed fillets, as the monitor
// promises. A refit of 50 fillets' extremes read a tail shape of 0.26 where the learned one
// is 0.12 and said re-learn on a product that had not changed (cartilage_heavy's clean run:
// 0.72 % implied; 0.24 % at 200 fillets, learned 0.02 %).
class DriftTracker {
 public:
  explicit DriftTracker(int window = 200, int every = 10, int min_fillets = 200)
      : window_(window), every_(every), min_(min_fillets) {}

  // A passed fillet's extremes under `learned`; returns true when the estimate was refreshed
  // (every `every` fillets once the window holds `min_fillets`). A different learned version
  // starts the window afresh.
  bool add(const LearnedDetection& learned, const std::vector<BandExtreme>& extremes);
  // The estimate over the window as it stands now (a run's end, between refreshes).
  void refresh(const LearnedDetection& learned);
  const DriftEstimate& estimate() const { return est_; }
  int min_fillets() const { return min_; }
  // The last window implies more than twice the target (and holds enough fillets to say).
  bool drifting(const LearnedDetection& learned) const {
    return est_.fillets >= min_ && est_.implied_frr > 2 * learned.target_frr;
  }
  // What the lane shows under `learned` after each fillet: nothing for a version the window
  // was not filled under (a newly activated one restarts it; the last one's rate and warning
  // must not stay on show for its first 200 fillets), nor without learned thresholds.
  DriftShown shown(const LearnedDetection& learned) const;

 private:
  int window_, every_, min_;
  std::string version_;
  std::deque<std::vector<BandExtreme>> recent_;
  int since_ = 0;
  DriftEstimate est_;
};

// "lane 2: product rougher than learned: re-learn (the last 200 passed fillets imply 0.91 %
// false rejects)": one wording for the log, statistics and the dashboard.
std::string product_drift_warning(int lane, int fillets, double implied_frr);

}  // namespace rangex
