// The server's product drift monitor (pipeline/product_drift.h) run over inspected
// records: a recording's passed fillets (rangexctl process), or several runs of one product
// one after the other (eval-matrix's clean runs), in the order they were inspected. It tells
// offline what a live lane's statistics would have said: whether the product's extremes
// follow the learned model, or imply more false rejects than the learning promised.
#pragma once
#include <string>
#include <vector>

#include "core/learned_detection.h"
#include "offline/fillet_records.h"
#include "pipeline/product_learning.h"

namespace rangex {

struct RecordedDrift {
  int passed = 0;          // passed fillets followed
  DriftEstimate last;      // over the last window at the end (implied_frr -1: too few)
  bool drifting = false;   // the last window says so
  int first_flagged = -1;  // the passed fillet (counted from 1) at which it first said so
  double highest_frr = 0;  // the highest rate any window of enough fillets implied
  double learned_frr = 0;  // what the learned models imply at their thresholds
  double target_frr = 0;   // the learning's target
  int min_fillets = 0;     // the tracker says nothing over fewer passed fillets
};

// Lane `lane`'s passed fillets of `runs`, in order, through a DriftTracker with the
// server's window (200 fillets, refreshed every 10 once it holds them; fewer say nothing,
// `last.implied_frr` -1). Throws Error when `learned` is not active.
RecordedDrift recorded_drift(const LearnedDetection& learned, const std::vector<RecordSet>& runs,
                             int lane);

// One line for rangexctl's output: "lane 0: drift monitor: the last 200 of 590 passed fillets
// imply 0.05 % false rejects at the learned thresholds (learned: 0.03 %, target 0.30 %)",
// the server's warning when the last window drifts, or why it says nothing yet.
std::string drift_sentence(int lane, const RecordedDrift& d);

// The same as a JSON object (process's summary.json, eval-matrix's matrix.json).
std::string drift_json(const RecordedDrift& d);

}  // namespace rangex
