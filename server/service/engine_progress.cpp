// Durable counts: what a feeder may forget. A lane's line is durable once its outcome is in
// the store: the fillet it belongs to was decided and committed, or its row was settled as
// belt. The count kept is conservative by the lines that rebuilding what follows needs (the
// X-ray delay, and a lead-in of belt for the assembly), so that after a crash the lines a
// feeder resends from it give the same fillets. It is saved in the store (every 50 ms, one
// transaction for all lanes) before any acknowledgement carries it; a restarted server
// resumes each lane from it (resent lines up to it are duplicates) and does not decide again
// a fillet it had decided (docs/concurrency.md).
#include <algorithm>
#include <cstdio>

#include "core/log.h"
#include "service/engine.h"

namespace rangex {

int64_t Engine::durable_margin(const Lane& l) const {
  const LaneConfig& c = l.config;
  return int64_t(c.xray.delay_lines) + std::max(64, c.inspection.gap_lines + 1) + 1;
}

void Engine::resume_from_store() {
  // Fillet numbers go on from the store's: two "fillet 0" records on one lane confuse anyone
  // reading the record.
  for (auto& l : lanes_) l->proc->set_next_fillet_id(store_.next_lane_fillet(l->id));
  for (const auto& [id, durable] : store_.progress()) {
    const auto it = by_id_.find(id);
    if (it == by_id_.end()) continue;  // a lane the plant no longer has
    Lane& l = *it->second;
    l.admission.resume(durable);
    l.durable_saved = durable;
    l.decided_until = store_.last_fillet_end(id).value_or(INT64_MIN);
    log::info("lane_resumes", "lane {} resumes after count {} (durable before the stop)", id,
              durable);
  }
  // A lane moved here from another server goes on from that server's record of it.
  for (const auto& [id, c] : opt_.continue_lanes) {
    const auto it = by_id_.find(id);
    if (it == by_id_.end()) continue;
    Lane& l = *it->second;
    l.proc->set_next_fillet_id(std::max(l.proc->next_fillet_id(), c.next_fillet));
    l.decided_until = std::max(l.decided_until, c.decided_until);
  }
}

void Engine::note_assembly(Lane& l) {
  const int64_t from = l.proc->pending_from();
  l.assembly_durable = from == INT64_MIN ? INT64_MIN : from - durable_margin(l);
  // A restarted assembly holds nothing: everything given to it is settled.
  l.assembly_settled = from == INT64_MIN ? l.last_pushed : from - 1;
}

std::vector<LaneProgress> Engine::progress() {
  std::vector<LaneProgress> out;
  for (auto& lp : lanes_) {
    Lane& l = *lp;
    LaneProgress p;
    p.lane = l.id;
    p.durable = l.durable_saved;
    int64_t s = l.assembly_settled;
    if (s != INT64_MIN) {
      std::lock_guard<std::mutex> lock(l.pending_mu);
      for (const auto& [first, bound] : l.pending_fillets) s = std::min(s, first - 1);
    }
    p.settled = s;
    if (p.durable != INT64_MIN || p.settled != INT64_MIN) out.push_back(p);
  }
  return out;
}

bool Engine::fillet_cut(Lane& l, const FilletImage& img) {
  if (img.first_encoder <= l.decided_until) {
    log::info("fillet_decided_before",
              "lane {}: the fillet at counts {}..{} was decided before the restart; not deciding "
              "it again",
              l.id, img.first_encoder, img.first_encoder + img.rows - 1);
    return false;
  }
  std::lock_guard<std::mutex> lock(l.pending_mu);
  l.pending_fillets.emplace(img.first_encoder, img.first_encoder - durable_margin(l));
  return true;
}

void Engine::fillet_stored(int lane_id, int64_t first_encoder) {
  Lane& l = lane(lane_id);
  std::lock_guard<std::mutex> lock(l.pending_mu);
  const auto it = l.pending_fillets.find(first_encoder);
  if (it != l.pending_fillets.end()) l.pending_fillets.erase(it);
}

void Engine::save_progress() {
  std::vector<std::pair<int, int64_t>> changed;
  for (auto& lp : lanes_) {
    Lane& l = *lp;
    // The assembly first: a fillet it has cut is pending before its count moves past it.
    int64_t d = l.assembly_durable;
    if (d == INT64_MIN) continue;
    {
      std::lock_guard<std::mutex> lock(l.pending_mu);
      for (const auto& [first, bound] : l.pending_fillets) d = std::min(d, bound);
    }
    if (d != l.durable_saved) changed.push_back({l.id, d});
  }
  if (changed.empty()) return;
  try {
    store_.save_progress(changed);
  } catch (const std::exception& e) {
    // Acknowledgements keep the last saved counts; feeders keep their lines meanwhile.
    if (!progress_failed_)
      log::error("durable_counts_not_saved", "durable counts not saved: {}", e.what());
    progress_failed_ = true;
    return;
  }
  progress_failed_ = false;
  for (const auto& [id, d] : changed) lane(id).durable_saved = d;
}

void Engine::progress_loop() {
  std::unique_lock<std::mutex> lock(progress_mu_);
  while (
      !progress_cv_.wait_for(lock, std::chrono::milliseconds(50), [&] { return progress_stop_; })) {
    lock.unlock();
    save_progress();
    lock.lock();
  }
}

}  // namespace rangex
