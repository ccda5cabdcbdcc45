// Detection figures against the simulator's truth: fragment recall by size and
// calcification, false rejects of clean fillets, position error, residual statistics; for
// rangex and for the X-ray-only baseline on the same fillets.
#pragma once
#include <string>
#include <vector>

#include "evaluation.h"
#include "fillet_records.h"

namespace rangex {

struct TruthFragment {
  int lane = 0, fillet = 0;
  std::string kind;  // bone | air | cartilage
  double x_mm = 0, b_mm = 0, size_mm = 0, calcification = 0;
  std::string shape = "compact";  // compact | needle | chip | rib | cluster
};

struct TruthFillet {
  int lane = 0, fillet = 0;
  double b_start = 0, b_end = 0;
  int bones = 0;
};

// Parse the simulator's truth/fragments.csv and truth/fillets.csv of one lane.
std::vector<TruthFragment> parse_truth_fragments(const std::string& text, int lane);
std::vector<TruthFillet> parse_truth_fillets(const std::string& text, int lane);

constexpr int kSizeBins = 4;  // 1-2, 2-3, 3-5, 5-10 mm
constexpr int kCalcBins = 2;  // weakly calcified (< 0.6), calcified (>= 0.6)
constexpr double kCalcified = 0.6;

struct DetectionEval {
  int found[kSizeBins][kCalcBins] = {};
  int total[kSizeBins][kCalcBins] = {};
  int in_rejected[kSizeBins][kCalcBins] = {};  // bone's fillet rejected for any reason
  int fillets = 0, not_inspected = 0, unmatched_truth_fillets = 0;
  int clean_fillets = 0, clean_rejected = 0, clean_not_inspected = 0;
  int bony_fillets = 0, bony_rejected = 0;
  int false_fragments = 0;                     // detected bones that match no true bone
  ErrorAccumulator position{1e-3, 100.0};      // mm
  double resid_mean_dn = 0, resid_std_dn = 0;  // pooled over inspected fillets
  long resid_pixels = 0;

  double recall_calcified_2mm() const;  // calcified fragments >= 2 mm
  double false_reject_rate() const;     // clean fillets rejected for any reason
};

// Adds one lane's truth and results into `e` (call per lane, then finish()).
void add_lane(DetectionEval& e, const std::vector<TruthFragment>& frags,
              const std::vector<TruthFillet>& fillets, const RecordSet& results);
void finish(DetectionEval& e);

std::string detection_table(const DetectionEval& ours, const DetectionEval& baseline, int bits);
std::string detection_json(const DetectionEval& ours, const DetectionEval& baseline, int bits);

}  // namespace rangex
