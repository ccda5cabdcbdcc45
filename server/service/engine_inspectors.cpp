// The inspectors: each takes the oldest cut fillet whose lane no other inspector holds,
// inspects it (an inspection that throws fails safe), counts it, hands the decision to the
// recorder and follows the lane's product drift.
#include <algorithm>
#include <cstdio>
#include <optional>

#include "core/log.h"
#include "service/engine.h"
#include "service/steady_ns.h"

namespace rangex {

void Engine::inspector() {
  while (true) {
    std::optional<InspectJob> job;
    {
      std::unique_lock<std::mutex> lock(inspect_mu_);
      // The first fillet whose lane no other inspector holds: each lane's decisions stay in
      // order. Idle, it wakes every 100 ms: unsaved decisions need looking after.
      auto ready = [&] {
        return std::find_if(inspect_queue_.begin(), inspect_queue_.end(),
                            [](const InspectJob& j) { return !j.lane->inspecting; });
      };
      inspect_cv_.wait_for(lock, std::chrono::milliseconds(100), [&] {
        return ready() != inspect_queue_.end() || (inspect_stop_ && inspect_queue_.empty());
      });
      const auto it = ready();
      if (it != inspect_queue_.end()) {
        job.emplace(std::move(*it));
        inspect_queue_.erase(it);
        job->lane->inspecting = true;
        inspect_room_.notify_all();
      } else if (inspect_stop_ && inspect_queue_.empty()) {
        break;
      }
    }
    if (job) {
      inspection_wait_.add((steady_ns() - job->queued_ns) / 1e6);
      const FilletImage& im = job->image;
      InspectedFillet f;
      f.result.lane = im.lane, f.result.id = im.id, f.result.first_line = im.first_line;
      f.result.first_encoder = im.first_encoder, f.result.rows = im.rows;
      f.result.y0_mm = im.y0_mm;
      try {
        f = inspect_image(std::move(job->image), job->params,
                          LaneProcessorOptions{false, opt_.images});
      } catch (const std::exception& e) {
        // Uninspected product is never passed: the fillet fails safe.
        f.result.decision = Decision::kNotInspected;
        f.result.reason = std::string("inspection failed: ") + e.what();
        log::error("inspection_failed", "lane {}: {}", job->lane->id, f.result.reason);
      }
      on_fillet(*job, std::move(f));
      {
        std::lock_guard<std::mutex> lock(inspect_mu_);
        job->lane->inspecting = false;
      }
      // The lane's next fillet may be waiting for it.
      inspect_cv_.notify_all();
    }
    recorder_.retry();
  }
}

void Engine::on_fillet(const InspectJob& job, InspectedFillet&& f) {
  const FilletResult& r = f.result;
  inspection_.add(f.inspect_ms);
  for (int k = 0; k < kStages; ++k) inspection_stage_[k].add(1e3 * r.stage_seconds[k]);
  collect_result(*job.lane, r);
  // Drift is followed once the decision is out (below): its refit is not the decision's.
  const bool passed = r.decision == Decision::kPass;
  std::vector<BandExtreme> extremes = passed ? r.extremes : std::vector<BandExtreme>{};
  ++fillets_;
  rejects_ += r.decision == Decision::kReject;
  not_inspected_ += r.decision == Decision::kNotInspected;
  ++job.lane->fillets;
  job.lane->rejects += r.decision == Decision::kReject;
  job.lane->not_inspected += r.decision == Decision::kNotInspected;
  recorder_.record(std::move(f), job.calibration, job.last_arrival_ns);
  if (passed) track_drift(*job.lane, job.params.learned, extremes);
}

void Engine::track_drift(Lane& l, const LearnedDetection& learned,
                         const std::vector<BandExtreme>& extremes) {
  // The inspector holds the lane, so the tracker is this thread's. The lane shows what the
  // tracker holds after each fillet, not only at a refresh (DriftTracker::shown).
  if (learned.active()) l.drift.add(learned, extremes);
  const DriftShown s = l.drift.shown(learned);
  l.implied_frr = s.implied_frr;
  l.drift_fillets = s.fillets;
  const bool was = l.product_drift.exchange(s.drifting);
  if (s.drifting && !was)
    log::warn("product_drift", "{} against a target of {:.2f} %",
              product_drift_warning(l.id, s.fillets, s.implied_frr), 100 * learned.target_frr);
}

}  // namespace rangex
