// Accuracy against the simulator's truth: stripe rows per camera column and X-ray path
// thickness over fillet pixels.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "core/lane_config.h"
#include "core/recording.h"

namespace rangex {

struct ErrorStats {
  size_t count = 0;
  double mean_abs = 0, p99_abs = 0, bias = 0;
};

// Streams errors in without keeping them: the p99 comes from a histogram of |error| with
// `resolution` wide bins (exact to that resolution).
class ErrorAccumulator {
 public:
  explicit ErrorAccumulator(double resolution = 1e-3, double max_abs = 100.0);
  void add(double e);
  void merge(const ErrorAccumulator& o);
  ErrorStats stats() const;

 private:
  double res_;
  std::vector<uint32_t> hist_;
  size_t count_ = 0;
  double sum_ = 0, sum_abs_ = 0;
};

struct LaneEvaluation {
  int lane = 0;
  ErrorStats stripe[2];                // px, columns valid in both truth and measurement
  ErrorStats stripe_fillet[2];         // px, the same restricted to columns on a fillet
  double stripe_detected[2] = {0, 0};  // fraction of truth stripe columns found
  double stripe_false[2] = {0, 0};     // fraction of no-stripe columns reported valid
  ErrorStats thickness;                // mm, fillet pixels with a valid measurement
  double fillet_coverage = 0;          // fraction of fillet pixels with a valid measurement
};

constexpr double kFilletPixelMinMm = 0.5;   // truth path thickness that counts as fillet
constexpr double kFilletColumnMinMm = 1.0;  // truth stripe height that counts as fillet

// The lane's measured stripe rows and registered thickness against truth/ of `rec`; the
// lane's geometry tells which stripe columns lie on a fillet.
LaneEvaluation evaluate_lane(const RecordingReader& rec, const LaneConfig& lane,
                             const std::vector<float> stripe_rows[2],
                             const std::vector<float>& thickness);

std::string evaluations_json(const std::vector<LaneEvaluation>& e);
std::string evaluations_table(const std::vector<LaneEvaluation>& e);

}  // namespace rangex
