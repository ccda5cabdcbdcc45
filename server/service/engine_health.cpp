// Health (serving, store) and statistics: counters, rates, latencies and warnings, read
// without waiting for ingest.
#include <cstdio>
#include <filesystem>

#include "core/error.h"
#include "core/open_file_limit.h"
#include "service/engine.h"
#include "service/steady_ns.h"

namespace rangex {

// Forwarding further behind than this is worth a look (a slow or overloaded database).
constexpr double kForwardLagWarnS = 60;

Health Engine::health() {
  Health h;
  const int64_t now = steady_ns(), stall = seconds_ns(opt_.stall_s);
  if (stopping_flag_) h.reasons.push_back("shutting down");
  const int64_t started = batch_started_ns_;
  char buf[160];
  if (started && now - started > stall) {
    std::snprintf(buf, sizeof buf, "worker stalled: one batch has been running for %.1f s",
                  (now - started) / 1e9);
    h.reasons.push_back(buf);
  } else {
    std::lock_guard<std::mutex> lock(mu_);
    const int64_t oldest = queue_.oldest_arrival_ns();
    if (!started && !queue_.empty() && now - oldest > stall) {
      std::snprintf(buf, sizeof buf, "worker not taking lines: %zu queued, the oldest for %.1f s%s",
                    queue_.size(), (now - oldest) / 1e9, paused_ ? " (paused)" : "");
      h.reasons.push_back(buf);
    }
  }
  size_t waiting = 0;
  const std::string store_error = recorder_.error(&waiting);
  if (!store_error.empty()) {
    h.store_ok = false;
    h.reasons.push_back("store failed: " + store_error + " (" + std::to_string(waiting) +
                        " decisions waiting to be stored)");
  }
  h.serving = h.reasons.empty();
  return h;
}

EngineStats Engine::stats() {
  EngineStats s;
  s.received = received_;
  s.accepted = accepted_;
  s.processed = processed_;
  s.fillets = fillets_;
  s.rejects = rejects_;
  s.not_inspected = not_inspected_;
  s.store_errors = recorder_.errors();
  s.bytes_parsed = bytes_parsed_;
  s.bytes_xray_copied = bytes_xray_copied_;
  for (size_t i = 0; i < kRefusals; ++i)
    if (const uint64_t n = refused_[i]) s.refused[std::string(refusal_name(Refusal(i)))] = n;
  for (size_t i = 0; i < kDropReasons; ++i)
    if (const uint64_t n = dropped_[i]) s.dropped[std::string(drop_name(DropReason(i)))] = n;
  for (auto& l : lanes_) s.lane_restarts += l->restarts;
  {
    const int64_t now = steady_ns();
    std::lock_guard<std::mutex> lock(mu_);
    for (auto& l : lanes_)
      if (l->last_line_ns && now - l->last_line_ns > seconds_ns(opt_.idle_close_s))
        s.warnings.push_back(join("lane ", l->id, " stopped being fed: no line for ",
                                  (now - l->last_line_ns) / 1'000'000'000, " s"));
  }
  for (auto& l : lanes_)
    if (l->product_drift)
      s.warnings.push_back(product_drift_warning(l->id, l->drift_fillets, l->implied_frr));
  {
    // A sensor not streaming leaves its lane blind: every fillet there goes uninspected.
    std::lock_guard<std::mutex> lock(sensors_mu_);
    if (sensor_states_)
      for (const LaneSensors& ls : sensor_states_())
        for (const SensorState& d : ls.devices)
          if (d.state != "streaming")
            s.warnings.push_back(join("lane ", ls.lane, " ", d.role, " (", d.device, ") ", d.state,
                                      d.error.empty() ? "" : ": " + d.error));
    s.recording = shift_->status();
    if (s.recording.active && s.recording.left_out)
      s.warnings.push_back(join("recording ", s.recording.name, ": ", s.recording.left_out,
                                " lines left out (the disk is slower than the lanes)"));
    if (plc_status_) {
      s.plc = plc_status_();
      // Lanes go on inspecting and storing; the PLC diverts what it is not told to release.
      if (!s.plc->connected)
        s.warnings.push_back(join("PLC ", s.plc->address, " unreachable: ", s.plc->error, "; ",
                                  s.plc->unreleased, " clean fillets unreleased (diverted), ",
                                  s.plc->pending, " waiting"));
      else if (!s.plc->refused.empty())
        s.warnings.push_back(s.plc->refused);
    }
  }
  s.forwarding = forwarding();
  if (s.forwarding) {
    // Inspection goes on; the records wait in the local store, which retention keeps.
    const ForwarderStatus& f = *s.forwarding;
    if (!f.connected)
      s.warnings.push_back(join("forwarding to PostgreSQL (", f.database, ") ", f.state, ": ",
                                f.lag_records, " records (", int64_t(f.lag_seconds),
                                " s) wait in the local store: ", f.last_error));
    else if (f.lag_seconds > kForwardLagWarnS)
      s.warnings.push_back(join("forwarding to PostgreSQL behind: ", f.lag_records, " records (",
                                int64_t(f.lag_seconds), " s) wait in the local store"));
  }
  {
    const OpenFiles f = open_files();
    s.open_files = f.open;
    s.open_files_limit = f.limit;
    if (f.open >= 0 && f.limit > 0 && double(f.open) >= kOpenFilesWarnShare * double(f.limit))
      s.warnings.push_back(join("open files: ", f.open, " of the limit of ", f.limit,
                                ": near it, new connections and files are refused (\"Too many "
                                "open files\"); a client may be holding many connections"));
  }
  if (opt_.store_reserve_mb > 0) {
    std::error_code ec;
    const auto space = std::filesystem::space(store_.dir(), ec);
    if (!ec && double(space.available) < opt_.store_reserve_mb * 1048576.0)
      s.warnings.push_back(join("store volume: ", space.available >> 20,
                                " MB free, below the reserve of ", opt_.store_reserve_mb,
                                " MB: free space before the disk fills"));
  }
  {
    std::lock_guard<std::mutex> lock(rate_mu_);
    if (rate_.size() >= 2) {
      const double dt = (rate_.back().first - rate_.front().first) / 1e9;
      if (dt > 0) s.lines_per_second = double(rate_.back().second - rate_.front().second) / dt;
    }
  }
  s.queue_depth = int(queued_.load());
  s.queue_capacity = int(opt_.queue_lines);
  s.queue_wait = queue_wait_.summary();
  s.pipeline = pipeline_.summary();
  s.inspection = inspection_.summary();
  s.inspection_wait = inspection_wait_.summary();
  s.store = recorder_.store_latency();
  for (int k = 0; k < kStages; ++k)
    s.inspection_stages.emplace_back(inspect_stage_name(k), inspection_stage_[k].summary());
  s.decision = recorder_.decision_latency();
  s.health = health();
  s.backend = runner_->running();
  s.backend_note = runner_->note();
  s.batches = runner_->stats();
  return s;
}

}  // namespace rangex
