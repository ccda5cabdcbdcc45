#include "service/plant_history.h"

namespace rangex {

HistorySample PlantHistory::sample(const EngineStats& s, const std::vector<LaneState>& lanes,
                                   int64_t t_ns) {
  HistorySample h;
  h.t_ns = t_ns;
  h.processed = s.processed;
  h.fillets = s.fillets;
  h.rejects = s.rejects;
  h.not_inspected = s.not_inspected;
  h.decision_p50_ms = s.decision.p50;
  h.decision_p99_ms = s.decision.p99;
  h.inspection_p50_ms = s.inspection.p50;
  for (const LaneState& l : lanes)
    h.lanes.push_back(
        {l.config.id, l.received, l.processed, l.fillets, l.rejects, l.not_inspected});
  return h;
}

void PlantHistory::add(HistorySample s) {
  std::lock_guard<std::mutex> lock(mu_);
  samples_.push_back(std::move(s));
  while (samples_.size() > 2 && samples_.front().t_ns < samples_.back().t_ns - keep_ns_)
    samples_.pop_front();
}

std::vector<HistorySample> PlantHistory::since(int64_t since_ns) {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<HistorySample> out;
  for (const HistorySample& s : samples_)
    if (s.t_ns >= since_ns) out.push_back(s);
  return out;
}

bool PlantHistory::window(int64_t window_ns, HistorySample& older, HistorySample& latest) {
  std::lock_guard<std::mutex> lock(mu_);
  if (samples_.size() < 2) return false;
  latest = samples_.back();
  older = samples_.front();
  for (auto it = samples_.rbegin() + 1; it != samples_.rend(); ++it)
    if (it->t_ns <= latest.t_ns - window_ns) {
      older = *it;
      break;
    }
  return true;
}

}  // namespace rangex
