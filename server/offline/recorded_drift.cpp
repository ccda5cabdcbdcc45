#include "offline/recorded_drift.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <sstream>

#include "core/error.h"
#include "pipeline/product_drift.h"

namespace rangex {

RecordedDrift recorded_drift(const LearnedDetection& learned, const std::vector<RecordSet>& runs,
                             int lane) {
  if (!learned.active()) fail("drift: the lane has no learned detection to follow");
  DriftTracker tracker;
  RecordedDrift d;
  d.learned_frr = implied_false_reject_rate(learned);
  d.target_frr = learned.target_frr;
  d.min_fillets = tracker.min_fillets();
  // Each estimate (the tracker makes none of fewer than its minimum): the highest rate, and
  // where it first drifted.
  auto note = [&] {
    d.highest_frr = std::max(d.highest_frr, tracker.estimate().implied_frr);
    if (d.first_flagged < 0 && tracker.drifting(learned)) d.first_flagged = d.passed;
  };
  for (const RecordSet& run : runs) {
    std::map<int64_t, std::vector<BandExtreme>> of;
    for (const ExtremeRecord& e : run.extremes)
      if (e.lane == lane) of[e.fillet].push_back(e.extreme);
    for (const FilletRecord& f : run.fillets) {
      if (f.lane != lane || f.decision != "pass") continue;
      ++d.passed;
      const auto it = of.find(f.fillet);
      if (tracker.add(learned, it == of.end() ? std::vector<BandExtreme>{} : it->second)) note();
    }
  }
  // Fewer passed fillets than the tracker judges: no estimate, as a live lane shows none.
  if (d.passed < d.min_fillets) {
    d.last.implied_frr = -1;
    return d;
  }
  tracker.refresh(learned);
  note();
  d.last = tracker.estimate();
  d.drifting = tracker.drifting(learned);
  return d;
}

std::string drift_sentence(int lane, const RecordedDrift& d) {
  char b[400];
  if (d.last.fillets < d.min_fillets) {
    std::snprintf(b, sizeof b,
                  "lane %d: drift monitor: %d passed fillets, fewer than the %d it needs to say",
                  lane, d.passed, d.min_fillets);
    return b;
  }
  std::snprintf(b, sizeof b,
                "lane %d: drift monitor: the last %d of %d passed fillets imply %.3f %% false "
                "rejects at the learned thresholds (learned: %.3f %%, target %.2f %%)",
                lane, d.last.fillets, d.passed, 100 * d.last.implied_frr, 100 * d.learned_frr,
                100 * d.target_frr);
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

std::string drift_json(const RecordedDrift& d) {
  std::ostringstream os;
  os.precision(8);
  os << "{\"passed\": " << d.passed << ", \"last_window\": " << d.last.fillets
     << ", \"implied_frr\": " << d.last.implied_frr << ", \"learned_frr\": " << d.learned_frr
     << ", \"target_frr\": " << d.target_frr
     << ", \"drifting\": " << (d.drifting ? "true" : "false")
     << ", \"first_flagged\": " << d.first_flagged << ", \"highest_frr\": " << d.highest_frr << "}";
  return os.str();
}

}  // namespace rangex
