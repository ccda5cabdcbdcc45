// The last hour of the plant, sampled every few seconds from the engine's counters: what the
// dashboard's charts (throughput, decisions, latency) and its lane tiles' rates are drawn
// from. Counters are cumulative; rates are differences between samples.
#pragma once
#include <cstdint>
#include <deque>
#include <mutex>
#include <vector>

#include "service/engine.h"

namespace rangex {

struct LaneCounts {
  int lane = 0;
  uint64_t received = 0, processed = 0, fillets = 0, rejects = 0, not_inspected = 0;
};

struct HistorySample {
  int64_t t_ns = 0;  // wall clock
  uint64_t processed = 0, fillets = 0, rejects = 0, not_inspected = 0;
  double decision_p50_ms = 0, decision_p99_ms = 0, inspection_p50_ms = 0;
  std::vector<LaneCounts> lanes;
};

class PlantHistory {
 public:
  explicit PlantHistory(double keep_s = 3600) : keep_ns_(int64_t(keep_s * 1e9)) {}
  static HistorySample sample(const EngineStats& s, const std::vector<LaneState>& lanes,
                              int64_t t_ns);
  void add(HistorySample s);
  // Samples with t_ns >= since_ns, oldest first.
  std::vector<HistorySample> since(int64_t since_ns);
  // The latest sample and the newest one at least `window_ns` older than it (or the
  // oldest kept): a rate over the window. False with fewer than two samples.
  bool window(int64_t window_ns, HistorySample& older, HistorySample& latest);

 private:
  int64_t keep_ns_;
  std::mutex mu_;
  std::deque<HistorySample> samples_;
};

}  // namespace rangex
