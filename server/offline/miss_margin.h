// What finding a missed fragment would cost. A fillet whose bone the inspection missed is
// inspected again with a rejecting statistic's thresholds (round or needle, learned per
// band; or the fixed z threshold both share) scaled down, from 1 in steps, until a detection
// lies where the bone is. The largest such fraction says how far the bone stood below the
// thresholds; with learned thresholds, the learned extreme-value models say what share of
// clean fillets thresholds that low would reject. Each learned statistic is lowered on its
// own (the other left as learned) and the cheaper one is reported: a round fragment found by
// lowering the round thresholds should not be charged for the needle's. A miss found at 0.95
// of the thresholds is a near miss; one found at 0.5, where the models imply several percent
// of false rejects, is beyond what a threshold can buy.
#pragma once
#include <vector>

#include "offline/detection_eval.h"
#include "pipeline/inspection.h"
#include "pipeline/lane_processor.h"

namespace rangex {

struct MarginOptions {
  double step = 0.02;  // the fractions tried: 1, 1 - step, ...
  double floor = 0.3;  // down to this (lower, noise merges into blobs anywhere)
};

// Which thresholds were lowered: a learned statistic's (kStatRound, kStatNeedle), or every
// rejecting one (fixed thresholds: the z threshold they share).
constexpr int kEveryRejecting = -1;

struct MissMargin {
  int stat = kEveryRejecting;
  double found_at = 0;      // the largest fraction found at; 0: not down to the floor
  double implied_frr = -1;  // the learned models' false-reject rate there; -1: fixed thresholds
};

// `p` with the rejecting thresholds of `stat` (or all) scaled by f: learned ones per band,
// else the fixed z threshold.
InspectionParams scaled_thresholds(const InspectionParams& p, double f, int stat = kEveryRejecting);

// For a bone at (x_mm, b_mm) (across the belt, belt position, as detections are placed),
// matched within tol_mm as the evaluation matches it, in the fillet `img`.
MissMargin miss_margin(const FilletImage& img, const InspectionParams& p, double x_mm, double b_mm,
                       double tol_mm, const MarginOptions& o = {});

// The inspected fillet (with its pixels) whose box on the belt holds (x_mm, b_mm), or null.
const InspectedFillet* fillet_holding(const std::vector<InspectedFillet>& fillets, double x_mm,
                                      double b_mm);

// Each miss of `e` in the lane `lane`, in the inspected fillet (with its pixels) that holds
// its position: found_at, frr_at and margin_stat filled; misses in no such fillet are left
// unmeasured.
void measure_miss_margins(DetectionEval& e, int lane, const std::vector<InspectedFillet>& fillets,
                          const InspectionParams& p, const MarginOptions& o = {});

}  // namespace rangex
