// The batching worker: lines taken from the lanes' queues in batches, through the line
// stages (StageRunner), each line's results into its lane's LaneProcessor; lanes take their
// pending changes at a quiet line boundary, restart after errors, and close when no longer fed.
#include <algorithm>
#include <cstdio>
#include <cstring>

#include "core/error.h"
#include "core/log.h"
#include "service/engine.h"
#include "service/steady_ns.h"

namespace rangex {

void Engine::worker() {
  std::vector<Queued> batch;
  while (true) {
    {
      std::unique_lock<std::mutex> lock(mu_);
      // With a batch in flight the worker does not wait: it takes what is queued (or, with
      // nothing queued, finishes the batch). Idle, it wakes at least every 100 ms: idle
      // lanes and unsaved decisions need looking after.
      const bool busy = runner_->busy();
      if (!busy)
        cv_.wait_for(lock, std::chrono::milliseconds(100),
                     [&] { return (!queue_.empty() && !paused_) || stopping_; });
      if (!busy && !stopping_ && !paused_ && !queue_.empty() &&
          int(queue_.size()) < opt_.batch_lines)
        // Give a partial batch a moment to fill.
        cv_.wait_for(lock, std::chrono::milliseconds(opt_.batch_wait_ms), [&] {
          return int(queue_.size()) >= opt_.batch_lines || stopping_ || paused_;
        });
      if (queue_.empty() && stopping_ && !busy) break;
      if (!queue_.empty() && (!paused_ || stopping_)) {
        queue_.take(size_t(opt_.batch_lines), batch);
        for (const Queued& q : batch)
          if (q.line.queued_by) --*q.line.queued_by;
        queued_ = queue_.size();
      }
    }
    batch_started_ns_ = steady_ns();
    if (!batch.empty()) {
      if (opt_.batch_hook) opt_.batch_hook();
      process(batch);
      batch.clear();
    } else {
      runner_->finish_all();
    }
    batch_started_ns_ = 0;
    if (!runner_->busy()) close_idle_lanes();
  }
  runner_->finish_all();
  OpenFillets at_stop;
  {
    std::lock_guard<std::mutex> lock(mu_);
    at_stop = at_stop_;
  }
  for (auto& l : lanes_) {
    if (at_stop == OpenFillets::kHandBack) {
      // Undecided, not durable: the feeders resend its lines to the next server, which
      // decides it whole.
      if (!l->proc->quiet())
        log::info("fillet_handed_back",
                  "lane {}: the fillet coming in from count {} is handed back undecided (its "
                  "lines are not durable; feeders resend them)",
                  l->id, l->proc->pending_from());
      continue;
    }
    try {
      l->proc->finish();
    } catch (const std::exception& e) {
      log::error("lane_close_failed", "lane {}: closing its open fillets failed: {}", l->id,
                 e.what());
    }
    l->in_progress = false;
  }
  // The inspector finishes what was cut, then stops.
  {
    std::lock_guard<std::mutex> lock(inspect_mu_);
    inspect_stop_ = true;
  }
  inspect_cv_.notify_all();
  for (std::thread& t : inspectors_)
    if (t.joinable()) t.join();
  recorder_.flush();
  std::lock_guard<std::mutex> lock(done_mu_);
  done_ = true;
  done_cv_.notify_all();
}

void Engine::apply_pending(Lane& l) {
  if (!l.proc->quiet()) return;
  std::optional<LaneConfig> next;
  std::string id;
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    if (!l.pending) return;
    next = std::move(l.pending);
    id = l.pending_id.empty() ? l.calibration_id : l.pending_id;
    l.pending.reset();
    l.pending_id.clear();
    l.config = *next;
    l.calibration_id = id;
  }
  // The backends' tables first (what is in flight finishes with the old ones), then the
  // assembly and the inspection.
  runner_->update_lane(l.id, *next);
  l.proc->reconfigure(*next);
  l.running_calibration = id;
  std::lock_guard<std::mutex> lock(mu_);
  l.admit_calibration = id;
}

void Engine::restart_lane(Lane& l, const std::string& reason) {
  log::warn("lane_restart", "lane {} restarts: {}", l.id, reason);
  l.proc->restart(reason);
  l.assembly_restarts = l.proc->assembly().restarts;
  l.arrivals.clear();
  ++l.restarts;
  l.in_progress = !l.proc->quiet();
  l.decided_until = INT64_MIN;  // a new count sequence
  note_assembly(l);
  std::lock_guard<std::mutex> lock(ctl_mu_);
  l.last_restart = reason;
}

void Engine::note_assembly_restarts(Lane& l) {
  // Jumps beyond the encoder horizon restart the assembly from inside.
  const int64_t n = l.proc->assembly().restarts;
  if (n == l.assembly_restarts) return;
  l.restarts += uint64_t(n - l.assembly_restarts);
  l.assembly_restarts = n;
  const std::string why = l.proc->last_restart();
  log::warn("lane_restart", "lane {} restarts: {}", l.id, why);
  std::lock_guard<std::mutex> lock(ctl_mu_);
  l.last_restart = why;
}

bool Engine::changes_waiting(const std::vector<Queued>& batch) {
  std::vector<Lane*> changing;
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    for (auto& l : lanes_)
      if (l->pending) changing.push_back(l.get());
  }
  if (changing.empty()) return false;
  // A lane takes its change at a line boundary with no fillet in progress, and no batch in
  // flight may still use its old tables.
  runner_->finish_all();
  for (Lane* l : changing) apply_pending(*l);
  std::lock_guard<std::mutex> lock(ctl_mu_);
  for (const Queued& q : batch)
    if (lane(q.line.lane).pending) return true;
  return false;
}

void Engine::process(std::vector<Queued>& batch) {
  const int64_t start = steady_ns();
  for (const Queued& q : batch) queue_wait_.add((start - q.arrived_ns) / 1e6);
  if (!changes_waiting(batch)) {
    // The whole mixed-lane batch goes to the backend as one.
    runner_->launch(std::move(batch));
    return;
  }
  // A lane of this batch waits for a quiet moment to take its change: lines go one by one,
  // so that every line boundary is a chance (quiet stretches can be shorter than a batch).
  for (Queued& q : batch) {
    Lane& l = lane(q.line.lane);
    try {
      if (!q.restart.empty()) restart_lane(l, q.restart);
      q.restart.clear();
      apply_pending(l);
    } catch (const std::exception& e) {
      recover(l, std::string("processing error: ") + e.what());
    }
    std::vector<Queued> one;
    one.push_back(std::move(q));
    runner_->launch(std::move(one));
    runner_->finish_all();
  }
}

void Engine::route(std::vector<Queued>& lines, const LineResults& r) {
  uint64_t done = 0;
  for (size_t k = 0; k < lines.size(); ++k) {
    const Queued& q = lines[k];
    Lane& l = lane(q.line.lane);
    try {
      if (!q.restart.empty()) restart_lane(l, q.restart);
      l.arrivals.emplace_back(q.line.encoder, q.arrived_ns);
      push_line_results(*l.proc, q, r, k, lines.size(), l.xray);
      bytes_xray_copied_ += l.xray.size() * sizeof(uint16_t);
      l.last_pushed = q.line.encoder;
      ++done;
      ++l.processed;
    } catch (const std::exception& e) {
      // The lane's state is suspect: its open fillets end not inspected; the line is counted.
      ++dropped_[size_t(DropReason::kProcessingError)];
      ++l.dropped[size_t(DropReason::kProcessingError)];
      recover(l, std::string("processing error: ") + e.what());
    }
    // Arrival times are kept for the decision latency as long as a fillet can reach back.
    const size_t keep = size_t(l.config.inspection.max_segment_lines) +
                        size_t(l.config.xray.delay_lines) + 4 * size_t(opt_.batch_lines);
    while (l.arrivals.size() > keep) l.arrivals.pop_front();
    note_assembly_restarts(l);
    note_assembly(l);
    l.last_push_ns = steady_ns();
    l.in_progress = !l.proc->quiet();
  }
  processed_ += done;
  std::lock_guard<std::mutex> lock(rate_mu_);
  rate_.emplace_back(steady_ns(), processed_.load());
  while (rate_.size() > 2 && rate_.front().first < rate_.back().first - 2'000'000'000)
    rate_.pop_front();
}

void Engine::lose(std::vector<Queued>& lines, const std::string& why) {
  log::error("lines_lost", "{} lines lost: {}", lines.size(), why);
  dropped_[size_t(DropReason::kProcessingError)] += lines.size();
  std::vector<int> seen;
  for (const Queued& q : lines) {
    ++lane(q.line.lane).dropped[size_t(DropReason::kProcessingError)];
    if (std::find(seen.begin(), seen.end(), q.line.lane) != seen.end()) continue;
    seen.push_back(q.line.lane);
    recover(lane(q.line.lane), why);
  }
}

void Engine::recover(Lane& l, const std::string& why) {
  try {
    restart_lane(l, why);
  } catch (const std::exception& e2) {
    log::error("lane_restart_failed", "lane {}: restart after an error failed too: {}", l.id,
               e2.what());
    Lane* raw = &l;
    const int64_t next = l.proc->next_fillet_id();  // the numbering goes on
    l.proc = std::make_unique<LaneProcessor>(
        l.config, LaneProcessorOptions{false, opt_.images}, LaneProcessor::FilletSink{},
        [this, raw](FilletImage&& img) { on_image(*raw, std::move(img)); });
    l.proc->set_next_fillet_id(next);
    l.assembly_restarts = 0;
  }
}

void Engine::close_idle_lanes() {
  const int64_t now = steady_ns();
  for (auto& lp : lanes_) {
    Lane& l = *lp;
    std::string lost;
    {
      std::lock_guard<std::mutex> lock(mu_);
      lost.swap(l.end_now);
    }
    if (!lost.empty() && l.in_progress) {
      try {
        restart_lane(l, lost);
      } catch (const std::exception& e) {
        log::error("lane_close_failed", "lane {}: ending its fillets failed: {}", l.id, e.what());
      }
      continue;
    }
    if (!l.in_progress || now - l.last_push_ns < seconds_ns(opt_.idle_close_s)) continue;
    char why[128];
    std::snprintf(why, sizeof why, "lane stopped being fed: no line for %.0f s with a fillet open",
                  (now - l.last_push_ns) / 1e9);
    try {
      restart_lane(l, why);
    } catch (const std::exception& e) {
      log::error("lane_close_failed", "lane {}: closing an idle lane failed: {}", l.id, e.what());
    }
  }
}

void Engine::on_image(Lane& l, FilletImage&& img) {
  if (!fillet_cut(l, img)) return;
  collect_image(l, img);  // a live learning run keeps a copy
  InspectJob job{&l, std::move(img), l.config.inspection, l.running_calibration, 0, steady_ns()};
  // Decision latency runs from the arrival of the fillet's last line.
  const int64_t last = job.image.first_encoder + job.image.rows - 1;
  for (auto it = l.arrivals.rbegin(); it != l.arrivals.rend(); ++it)
    if (it->first <= last) {
      job.last_arrival_ns = it->second;
      break;
    }
  std::unique_lock<std::mutex> lock(inspect_mu_);
  inspect_room_.wait(lock, [&] { return inspect_queue_.size() < kMaxInspectQueue; });
  inspect_queue_.push_back(std::move(job));
  inspect_cv_.notify_one();
}

}  // namespace rangex
