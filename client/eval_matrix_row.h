// One plant variant's results in the matrix (client/cmd_eval_matrix.cpp), and the matrix's
// options: what the run fills in and the report (eval_matrix_report.h) reads.
#pragma once
#include <string>
#include <vector>

#include "eval_bone_run.h"
#include "eval_claims.h"
#include "learning_check.h"
#include "offline/detection_eval.h"
#include "offline/evaluation.h"
#include "offline/recorded_drift.h"

namespace rangex::cli {

struct MatrixRow {
  std::string name;
  bool held_out = false;
  ErrorStats thickness;
  DetectionEval ours, base;
  // With thresholds learned from the variant's own clean fillets (another seed), and what
  // the learning reported: ok, fillets it flagged as bone-like, its sensitivity claims
  // checked on a third set of clean fillets.
  DetectionEval learned;
  int learn_fillets = 0;
  bool learned_run = false, learn_ok = false;
  int learn_flagged = 0, claims = 0, claims_held = 0, claims_contradicted = 0;
  std::vector<std::string> claims_not_held;  // by band, as the check says them
  LearningCheck check;  // the fillets its learnings named, checked against the truth
  // The report's sentences checked on the check fillets, and their pieces pooled.
  int stated = 0, stated_held = 0, stated_found = 0, stated_injected = 0;
  // A large run of clean product alone with the learned thresholds: the false-reject rate
  // with an interval narrow enough to mean something.
  int frr_fillets = 0, frr_rejected = 0, frr_not_inspected = 0;
  int frr_fragments = 0;  // bone detections in the clean run
  // What the lane's drift monitor said over the clean run's passed fillets, in order:
  // whether the product's extremes follow the model learned from its learning fillets.
  RecordedDrift drift;
  std::string drift_sentence;
  std::vector<std::string> sensitivity;
  // More bony fillets with the learned thresholds (--bones): recall with a narrow interval.
  std::vector<BonePart> bones;
  // The report's sphere claims held against the plant's and the bone run's fragments.
  FragmentClaims fragment_claims;
  bool claims_measured = false;
  int cartilage = 0;  // pieces of cartilage or tendon in the plant's fillets (its truth)
  double minutes = 0;
  std::string failed;  // why the variant stopped (its log says more); empty when it ran
};

struct MatrixOptions {
  int fillets = 60;
  long seed = 11;
  bool keep = false;
  int learn_fillets = 40;  // 0: no learning
  int check_fillets = 20;
  int frr_fillets = 0;     // clean fillets inspected with the learned thresholds (0: none)
  int frr_part = 60;       // simulated, inspected and dropped this many at a time
  int bone_fillets = 0;    // more bony fillets inspected with the learned thresholds (0: none)
  std::string confidence;  // learn's --confidence ("": learn's default)
  std::string tail_from;   // learn's --tail-from ("": learn's default)
};

}  // namespace rangex::cli
