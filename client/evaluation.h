// Accuracy against the simulator's truth: stripe rows per camera column and X-ray path
// thickness over fillet pixels.
#pragma once
#include <string>
#include <vector>

#include "core/recording.h"
#include "replay.h"

namespace rangex {

struct ErrorStats {
  size_t count = 0;
  double mean_abs = 0, p99_abs = 0, bias = 0;
};

ErrorStats error_stats(std::vector<double> signed_errors);

struct LaneEvaluation {
  int lane = 0;
  ErrorStats stripe[2];           // px, columns valid in both truth and measurement
  double stripe_detected[2] = {0, 0};  // fraction of truth stripe columns found
  double stripe_false[2] = {0, 0};     // fraction of no-stripe columns reported valid
  ErrorStats thickness;           // mm, fillet pixels with a valid measurement
  double fillet_coverage = 0;     // fraction of fillet pixels with a valid measurement
};

constexpr double kFilletPixelMinMm = 0.5;  // truth path thickness that counts as fillet

// The lane's measured stripe rows and registered thickness against truth/ of `rec`.
LaneEvaluation evaluate_lane(const RecordingReader& rec, int lane,
                             const std::vector<float> stripe_rows[2],
                             const std::vector<float>& thickness);

std::string evaluations_json(const std::vector<LaneEvaluation>& e);
std::string evaluations_table(const std::vector<LaneEvaluation>& e);

}  // namespace rangex
