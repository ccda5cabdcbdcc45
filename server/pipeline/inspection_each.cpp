// One fillet decided under several sets of learned thresholds that read the same statistics:
// what learning's trade-off asks of every test piece (each false-reject target's thresholds
// on the same pieces). The model and the statistics are most of an inspection's time; the
// thresholds and components that follow are a small part of it.
#include <algorithm>

#include "pipeline/inspection.h"
#include "pipeline/inspection_steps.h"

namespace rangex {

namespace {

// Whether two sets of thresholds are applied to the same statistics: the same kernels, and
// the same spread and rim where learned settings choose them (inspection.cpp).
bool same_statistics(const LearnedDetection& a, const LearnedDetection& b) {
  if (a.active() != b.active() || !(a.matched == b.matched)) return false;
  return !a.active() ||
         (a.spread_by_thickness == b.spread_by_thickness && a.rim_walls == b.rim_walls);
}

}  // namespace

std::vector<FilletResult> inspect_fillet_each(const FilletImage& raw, const InspectionParams& p,
                                              const std::vector<LearnedDetection>& learned) {
  std::vector<FilletResult> out;
  out.reserve(learned.size());
  InspectionParams q = p;
  const bool shared = !inspected_in_dual_energy(raw, p) &&
                      std::all_of(learned.begin(), learned.end(), [&](const auto& l) {
                        return same_statistics(l, learned.front());
                      });
  if (!shared) {
    for (const LearnedDetection& l : learned) {
      q.learned = l;
      out.push_back(inspect_fillet(raw, q, false));
    }
    return out;
  }
  // Made in the first set's inspection, as inspect_fillet makes them; read by every other's.
  // Whether the fillet can be inspected, or searched, does not depend on the thresholds.
  OneEnergyModel m;
  DetectionStatistics ds;
  FilletResult made;
  bool have = false, modelled = false;
  for (const LearnedDetection& l : learned) {
    q.learned = l;
    out.push_back(inspect_searchable(raw, q, [&](const InspectionParams& qq, FilletResult& res) {
      if (!have) {
        have = true;
        modelled = one_energy_model(raw, qq, res, m);
        if (modelled) statistics_from_z(m.image(raw), m.use, m.z, m.closure_z, qq, res, ds);
        made = res;
      } else {
        res = made;
      }
      if (modelled)
        decide_from_statistics(m.image(raw), m.use, m.z, m.resid, &res.fit, ds, qq, false, res);
    }));
  }
  return out;
}

}  // namespace rangex
