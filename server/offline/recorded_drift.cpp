#include "offline/recorded_drift.h"

#include <algorithm>
#include <cstdio>
#include <map>

#include "core/error.h"
#include "pipeline/product_drift.h"

namespace rangex {

RecordedDrift recorded_drift(const LearnedDetection& learned, const std::vector<RecordSet>& runs,
                             int lane) {
  if (!learned.active()) fail("drift: the lane has no learned detection to follow");
  RecordedDrift d;
  d.learned_frr = implied_false_reject_rate(learned);
  DriftTracker tracker;
  for (const RecordSet& run : runs) {
    std::map<int64_t, std::vector<BandExtreme>> of;
    for (const ExtremeRecord& e : run.extremes)
      if (e.lane == lane) of[e.fillet].push_back(e.extreme);
    for (const FilletRecord& f : run.fillets) {
      if (f.lane != lane || f.decision != "pass") continue;
      ++d.passed;
      const auto it = of.find(f.fillet);
      if (!tracker.add(learned, it == of.end() ? std::vector<BandExtreme>{} : it->second)) continue;
      if (tracker.estimate().fillets < tracker.min_fillets()) continue;
      d.highest_frr = std::max(d.highest_frr, tracker.estimate().implied_frr);
      if (d.first_flagged < 0 && tracker.drifting(learned)) d.first_flagged = d.passed;
    }
  }
  tracker.refresh(learned);
  d.last = tracker.estimate();
  d.drifting = tracker.drifting(learned);
  if (d.last.fillets >= tracker.min_fillets()) {
    d.highest_frr = std::max(d.highest_frr, d.last.implied_frr);
    if (d.first_flagged < 0 && d.drifting) d.first_flagged = d.passed;
  }
  return d;
}

std::string drift_sentence(int lane, const RecordedDrift& d, const LearnedDetection& learned) {
  char b[400];
  const DriftTracker limits;
  if (d.last.fillets < limits.min_fillets()) {
    std::snprintf(b, sizeof b,
                  "lane %d: drift monitor: %d passed fillets, fewer than the %d it needs to say",
                  lane, d.passed, limits.min_fillets());
    return b;
  }
  std::snprintf(b, sizeof b,
                "lane %d: drift monitor: the last %d of %d passed fillets imply %.3f %% false "
                "rejects at the learned thresholds (learned: %.3f %%, target %.2f %%)",
                lane, d.last.fillets, d.passed, 100 * d.last.implied_frr, 100 * d.learned_frr,
                100 * learned.target_frr);
  std::string s = b;
  if (d.first_flagged > 0) {
    std::snprintf(b, sizeof b,
                  "; it warned first at passed fillet %d (the highest rate of any window: %.3f %%)",
                  d.first_flagged, 100 * d.highest_frr);
    s += b;
  }
  if (d.drifting) s += "\n" + product_drift_warning(lane, d.last.fillets, d.last.implied_frr);
  return s;
}

}  // namespace rangex
