#include "pipeline/product_drift.h"

#include <cstdio>

namespace rangex {

bool DriftTracker::add(const LearnedDetection& L, const std::vector<BandExtreme>& extremes) {
  if (!L.active()) return false;
  if (L.version != version_) {
    version_ = L.version;
    recent_.clear();
    since_ = 0;
    est_ = {};
  }
  recent_.push_back(extremes);
  while (int(recent_.size()) > window_) recent_.pop_front();
  // No estimate before the window holds its minimum: a number shown is one the monitor
  // would stand by (ListLanes' implied rate stays -1, not estimated yet).
  if (++since_ < every_ || int(recent_.size()) < min_) return false;
  refresh(L);
  return true;
}

void DriftTracker::refresh(const LearnedDetection& L) {
  since_ = 0;
  est_ = estimate_drift(L, std::vector<std::vector<BandExtreme>>(recent_.begin(), recent_.end()));
}

DriftShown DriftTracker::shown(const LearnedDetection& L) const {
  if (!L.active() || L.version != version_ || est_.fillets < min_) return {};
  return {est_.implied_frr, est_.fillets, drifting(L)};
}

std::string product_drift_warning(int lane, int fillets, double implied_frr) {
  char b[200];
  std::snprintf(b, sizeof b,
                "lane %d: product rougher than learned: re-learn (the last %d passed fillets "
                "imply %.2f %% false rejects)",
                lane, fillets, 100 * implied_frr);
  return b;
}

}  // namespace rangex
