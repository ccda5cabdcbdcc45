#include "offline/miss_margin.h"

#include <cmath>

#include "pipeline/product_learning.h"

namespace rangex {

InspectionParams scaled_thresholds(const InspectionParams& p, double f, int stat) {
  InspectionParams q = p;
  if (q.learned.active()) {
    for (int s = 0; s < kStatistics; ++s)
      if (s != kStatAir && (stat == kEveryRejecting || s == stat))
        for (double& t : q.learned.stats[size_t(s)].thresholds) t *= f;
  } else {
    q.z_threshold *= f;
  }
  return q;
}

namespace {

// The largest fraction of `stat`'s thresholds that finds the bone (0: none down to the floor).
double found_at(const FilletImage& img, const InspectionParams& p, int stat, double x_mm,
                double b_mm, double tol_mm, const MarginOptions& o) {
  // Downward from 1: the first fraction that finds it is the largest (lower ones may merge
  // it with noise into a blob centred elsewhere).
  const int steps = int(std::floor((1 - o.floor) / o.step + 1e-9));
  for (int k = 0; k <= steps; ++k) {
    const double f = 1 - k * o.step;
    for (const Blob& b : inspect_fillet(img, scaled_thresholds(p, f, stat), false).fragments)
      if (std::hypot(b.x_mm - x_mm, b.y_mm - b_mm) <= tol_mm) return f;
  }
  return 0;
}

}  // namespace

MissMargin miss_margin(const FilletImage& img, const InspectionParams& p, double x_mm, double b_mm,
                       double tol_mm, const MarginOptions& o) {
  InspectionParams q = p;
  q.band_extremes = false;  // only the detections are wanted
  if (!p.learned.active())
    return {kEveryRejecting, found_at(img, q, kEveryRejecting, x_mm, b_mm, tol_mm, o), -1};
  MissMargin best;
  for (int s : {int(kStatRound), int(kStatNeedle)}) {
    MissMargin m{s, found_at(img, q, s, x_mm, b_mm, tol_mm, o), -1};
    if (m.found_at <= 0) continue;
    m.implied_frr = implied_false_reject_rate(scaled_thresholds(p, m.found_at, s).learned);
    if (best.found_at <= 0 || m.implied_frr < best.implied_frr) best = m;
  }
  return best;
}

const InspectedFillet* fillet_holding(const std::vector<InspectedFillet>& fillets, double x_mm,
                                      double b_mm) {
  for (const InspectedFillet& f : fillets) {
    const FilletImage& img = f.image;
    if (img.xray.empty() || f.result.decision == Decision::kNotInspected) continue;
    // Its box on the belt (x at mid-depth spreads by the fan beam's few percent: a margin).
    const double y1 = img.y0_mm + img.rows * img.step_mm;
    const double xa = f.result.x0_mm - 2, xb = f.result.x0_mm + img.cols * img.pitch_mm + 2;
    if (b_mm < img.y0_mm || b_mm > y1 || x_mm < xa || x_mm > xb) continue;
    return &f;
  }
  return nullptr;
}

void measure_miss_margins(DetectionEval& e, int lane, const std::vector<InspectedFillet>& fillets,
                          const InspectionParams& p, const MarginOptions& o) {
  for (MissedFragment& m : e.missed) {
    if (m.lane != lane) continue;
    const InspectedFillet* f = fillet_holding(fillets, m.x_mm, m.b_mm);
    if (!f) continue;
    const MissMargin mm = miss_margin(f->image, p, m.x_mm, m.b_mm, m.tol_mm, o);
    m.found_at = mm.found_at;
    m.frr_at = mm.implied_frr;
    m.margin_stat = mm.stat;
    m.margin_floor = o.floor;
  }
}

}  // namespace rangex
