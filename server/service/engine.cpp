#include "service/engine.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>

#include "core/calibration_report.h"
#include "core/error.h"
#include "core/size_limits.h"
#include "pipeline/fillet_images.h"
#include "service/line_shape.h"

namespace fs = std::filesystem;

namespace rangex {

namespace {
int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
int64_t seconds_ns(double s) {
  return int64_t(s * 1e9);
}
// Unsaved decisions kept while the store fails; beyond this the oldest leaves memory, loudly
// (its lines stay not durable: the feeders still hold them).
constexpr size_t kMaxUnsaved = 4096;
// After the store recovers, a lane whose lines were handed back refuses later counts this
// long at most while it waits for the first handed-back count to come again.
constexpr double kHandBackHoldS = 10;
}  // namespace

Engine::Lane::Lane(const LaneConfig& c, const EngineOptions& o, size_t slot)
    : id(c.id),
      slot(slot),
      width(c.frame_width),
      height(c.frame_height),
      pixels(c.xray.pixels),
      admission(c.id, o.dedup_window, o.auto_reset),
      config(c) {}

Engine::Engine(const PlantConfig& plant, Store& store, ResultsHub& hub, EngineOptions opt)
    : plant_(plant), store_(store), hub_(hub), opt_(std::move(opt)), queue_(plant_.lanes.size()) {
  for (const LaneConfig& lc : plant_.lanes) {
    auto l = std::make_unique<Lane>(lc, opt_, lanes_.size());
    l->calibration_id = plant_.calibration_id;
    // A calibration activated before a restart is active again.
    for (const StoredCalibration& c : store_.calibrations(lc.id))
      if (c.active) {
        l->config = apply_lane_calibration(lc, c.yaml, "calibration " + c.id);
        l->calibration_id = c.id;
      }
    // So are learned settings.
    for (const StoredSetting& s : store_.settings(SettingKind::kLearned, lc.id))
      if (s.active) apply_learned(l->config, s);
    l->admit_calibration = l->running_calibration = l->calibration_id;
    l->xray.resize(size_t(l->pixels));
    Lane* raw = l.get();
    l->proc = std::make_unique<LaneProcessor>(
        l->config, LaneProcessorOptions{false, opt_.images}, LaneProcessor::FilletSink{},
        [this, raw](FilletImage&& img) { on_image(*raw, std::move(img)); });
    by_id_[l->id] = l.get();
    lanes_.push_back(std::move(l));
  }
  std::vector<LaneConfig> configs;
  for (auto& l : lanes_) configs.push_back(l->config);
  runner_ = std::make_unique<StageRunner>(
      configs, StageRunnerOptions{opt_.backend, opt_.verify_fraction},
      [this](std::vector<Queued>& lines, const LineResults& r, double ms) {
        pipeline_.add(ms);
        route(lines, r);
      },
      [this](std::vector<Queued>& lines, const std::string& why) { lose(lines, why); });
  epoch_ = std::random_device{}() | uint64_t(std::random_device{}()) << 32 | 1;
  resume_from_store();
  for (int k = 0; k < opt_.inspectors; ++k) inspectors_.emplace_back([this] { inspector(); });
  worker_ = std::thread([this] { worker(); });
  progress_ = std::thread([this] { progress_loop(); });
}

Engine::~Engine() {
  drain_and_stop();
}

Engine::Lane& Engine::lane(int id) {
  const auto it = by_id_.find(id);
  if (it != by_id_.end()) return *it->second;
  fail_not_found("unknown lane ", id, " (the plant has lanes ", plant_.lanes.front().id, "..",
                 plant_.lanes.back().id, ")");
}

Engine::Verdict Engine::refuse(Lane* l, Refusal code, std::string message, size_t queued) {
  ++refused_[size_t(code)];
  if (l) ++l->refused[size_t(code)];
  Verdict v;
  v.code = code;
  v.message = std::move(message);
  v.credit = int(opt_.queue_lines - std::min(queued, opt_.queue_lines));
  if (l) v.durable = l->durable_saved;
  return v;
}

Engine::Verdict Engine::refuse_empty(uint64_t sequence) {
  ++received_;
  return refuse(nullptr, Refusal::kMissingLine,
                "request " + std::to_string(sequence) + " carries no line", queued_.load());
}

int Engine::free_places() const {
  return int(opt_.queue_lines - std::min(queued_.load(), opt_.queue_lines));
}

Engine::Verdict Engine::submit(IncomingLine&& line) {
  ++received_;
  bytes_parsed_ += line.cam0.size() + line.cam1.size() + line.xray.size();
  const auto found = by_id_.find(line.lane);
  Lane* l = found == by_id_.end() ? nullptr : found->second;
  if (!l)
    return refuse(nullptr, Refusal::kUnknownLane, "unknown lane " + std::to_string(line.lane),
                  queued_.load());
  ++l->received;
  if (auto bad = check_line_shape({l->id, l->width, l->height, l->pixels}, line))
    return refuse(l, bad->code, std::move(bad->message), queued_.load());

  // The checks against the lane's state and the update of that state are one step under
  // mu_: two streams on one lane can never both be accepted for a count.
  const int64_t now = steady_ns();
  Verdict v;
  {
    std::lock_guard<std::mutex> lock(mu_);
    // Idle counts from the last line received, refused ones too: a feeder that resends after
    // a restart is feeding the lane even while every line is a duplicate.
    l->last_line_ns = now;
    if (stopping_)
      return refuse(l, Refusal::kShuttingDown,
                    "the server is shutting down: line handed back, send it to the next one",
                    queue_.size());
    // While decisions cannot be stored, lines are handed back rather than accepted into
    // memory that an exit would lose; the lane then takes its counts in order again.
    if (line.encoder <= l->handback_from) l->handback_from = INT64_MAX;  // the resend is here
    if (store_failing_) {
      l->handback_from = std::min(l->handback_from, line.encoder);
      l->handback_ns = now;
      return refuse(l, Refusal::kStoreUnavailable,
                    "the store cannot write: line handed back, send it again when the store "
                    "recovers (health says why)",
                    queue_.size());
    }
    if (l->handback_from != INT64_MAX && now - l->handback_ns < seconds_ns(kHandBackHoldS))
      return refuse(l, Refusal::kStoreUnavailable,
                    join("line handed back: lane ", l->id, " waits for count ", l->handback_from,
                         ", handed back before it, to be sent again"),
                    queue_.size());
    l->handback_from = INT64_MAX;
    if (!line.calibration_id.empty() && line.calibration_id != l->admit_calibration)
      return refuse(l, Refusal::kCalibrationMismatch,
                    join("line made with calibration '", line.calibration_id, "' but lane ", l->id,
                         " runs '", l->admit_calibration, "'"),
                    queue_.size());
    LaneAdmission::Verdict a = l->admission.check(line.encoder);
    if (a.outcome == LaneAdmission::Outcome::kDuplicate)
      return refuse(l, Refusal::kDuplicateLine, std::move(a.message), queue_.size());
    if (a.outcome == LaneAdmission::Outcome::kBackwards)
      return refuse(l, Refusal::kEncoderBackwards, std::move(a.message), queue_.size());
    if (queue_.size() >= opt_.queue_lines)
      // The line is lost: its count stays unaccounted, so the assembly sees a gap and fails
      // the fillets around it safe.
      return refuse(l, Refusal::kOverload,
                    join("queue full (", opt_.queue_lines,
                         " lines); line dropped, its fillet will be rejected as not inspected"),
                    queue_.size());
    l->admission.commit(line.encoder, !a.restart.empty());
    if (line.queued_by) ++*line.queued_by;
    ++l->accepted;
    queue_.push(l->slot, {std::move(line), now, std::move(a.restart)});
    queued_ = queue_.size();
    ++accepted_;
    v.accepted = true;
    v.credit = int(opt_.queue_lines - queue_.size());
    v.durable = l->durable_saved;
  }
  cv_.notify_one();
  return v;
}

void Engine::pause(bool paused) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    paused_ = paused;
  }
  cv_.notify_all();
}

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
        std::fprintf(stderr,
                     "rangexd: lane %d: the fillet coming in from count %lld is handed back "
                     "undecided (its lines are not durable; feeders resend them)\n",
                     l->id, (long long)l->proc->pending_from());
      continue;
    }
    try {
      l->proc->finish();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "rangexd: lane %d: closing its open fillets failed: %s\n", l->id,
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
  flush_unsaved();
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
  std::fprintf(stderr, "rangexd: lane %d restarts: %s\n", l.id, reason.c_str());
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
  std::fprintf(stderr, "rangexd: lane %d restarts: %s\n", l.id, why.c_str());
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
  std::fprintf(stderr, "rangexd: %zu lines lost: %s\n", lines.size(), why.c_str());
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
    std::fprintf(stderr, "rangexd: lane %d: restart after an error failed too: %s\n", l.id,
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
    if (!l.in_progress || now - l.last_push_ns < seconds_ns(opt_.idle_close_s)) continue;
    char why[128];
    std::snprintf(why, sizeof why, "lane stopped being fed: no line for %.0f s with a fillet open",
                  (now - l.last_push_ns) / 1e9);
    try {
      restart_lane(l, why);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "rangexd: lane %d: closing an idle lane failed: %s\n", l.id, e.what());
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
        std::fprintf(stderr, "rangexd: lane %d: %s\n", job->lane->id, f.result.reason.c_str());
      }
      on_fillet(*job, std::move(f));
      {
        std::lock_guard<std::mutex> lock(inspect_mu_);
        job->lane->inspecting = false;
      }
      // The lane's next fillet may be waiting for it.
      inspect_cv_.notify_all();
    }
    std::lock_guard<std::mutex> lock(save_mu_);
    retry_unsaved();
  }
}

void Engine::flush_unsaved() {
  // Give the store a last chance with what it could not take.
  std::lock_guard<std::mutex> lock(save_mu_);
  for (int tries = 0; tries < 20 && !unsaved_.empty(); ++tries) {
    retry_unsaved();
    if (!unsaved_.empty()) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (!unsaved_.empty())
    std::fprintf(stderr, "rangexd: %zu decisions could not be stored before the stop\n",
                 unsaved_.size());
}

void Engine::on_fillet(const InspectJob& job, InspectedFillet&& f) {
  const FilletResult& r = f.result;
  inspection_.add(f.inspect_ms);
  for (int k = 0; k < kStages; ++k) inspection_stage_[k].add(1e3 * r.stage_seconds[k]);
  Unsaved u;
  StoredFillet& s = u.record;
  s.lane = r.lane;
  s.lane_fillet = r.id;
  s.first_encoder = r.first_encoder;
  s.rows = r.rows;
  s.decision = std::string(decision_name(r.decision));
  s.reason = r.reason;
  s.beta0 = r.fit.beta0;
  s.beta1 = r.fit.beta1;
  s.beta2 = r.fit.beta2;
  s.resid_mean_dn = r.resid_mean_dn;
  s.resid_std_dn = r.resid_std_dn;
  s.belt_y0_mm = r.y0_mm;
  s.decided_ns = now_ns();
  s.calibration_id = job.calibration;
  for (const auto* list : {&r.fragments, &r.air_pockets})
    for (const Blob& b : *list)
      s.fragments.push_back({list == &r.fragments ? "bone" : "air", b.x_mm, b.y_mm, b.area_mm2,
                             b.peak_z, b.attenuation_mm2, b.meat_mm, b.row0, b.row1, b.col0,
                             b.col1});
  u.last_arrival_ns = job.last_arrival_ns;
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
  u.fillet = std::move(f);
  // Decisions are published in order, each once it is stored.
  std::lock_guard<std::mutex> saving(save_mu_);
  retry_unsaved();
  if (!unsaved_.empty() || !save(u)) {
    if (unsaved_.size() >= kMaxUnsaved) {
      // Its lines stay not durable (still pending): the feeders resend them to a server that
      // can store the decision.
      std::fprintf(stderr,
                   "rangexd: the store has failed for %zu decisions; no longer held: lane %d "
                   "fillet %lld (%s), its lines are handed back\n",
                   unsaved_.size(), unsaved_.front().record.lane,
                   (long long)unsaved_.front().record.lane_fillet,
                   unsaved_.front().record.decision.c_str());
      unsaved_.pop_front();
    }
    unsaved_.push_back(std::move(u));
  }
  {
    std::lock_guard<std::mutex> lock(health_mu_);
    unsaved_count_ = unsaved_.size();
  }
  if (passed) track_drift(*job.lane, job.params.learned, extremes);
}

void Engine::track_drift(Lane& l, const LearnedDetection& learned,
                         const std::vector<BandExtreme>& extremes) {
  // The inspector holds the lane, so the tracker is this thread's.
  if (!learned.active() || !l.drift.add(learned, extremes)) return;
  const DriftEstimate& d = l.drift.estimate();
  l.implied_frr = d.implied_frr;
  l.drift_fillets = d.fillets;
  const bool was = l.product_drift.exchange(l.drift.drifting(learned));
  if (l.product_drift && !was)
    std::fprintf(stderr, "rangexd: %s against a target of %.2f %%\n",
                 product_drift_warning(l.id, d.fillets, d.implied_frr).c_str(),
                 100 * learned.target_frr);
}

bool Engine::save(Unsaved& u) {
  const int64_t t0 = steady_ns();
  StoredFillet& s = u.record;
  const FilletResult& r = u.fillet.result;
  auto failed = [&](const std::string& what) {
    ++store_errors_;
    store_failing_ = true;
    std::lock_guard<std::mutex> lock(health_mu_);
    if (store_error_.empty())
      std::fprintf(stderr, "rangexd: the store failed: %s; decisions wait until it recovers\n",
                   what.c_str());
    store_error_ = what;
    return false;
  };
  try {
    if (s.uid == 0) s.uid = store_.add_fillet(s);
  } catch (const std::exception& e) {
    return failed(e.what());
  }
  // The images are part of the decision: written whole (each renamed into place) and
  // registered, or retried with it. The decision is durable and published after them.
  if (opt_.images && !u.images_stored && r.decision != Decision::kPass &&
      !u.fillet.image.mask.empty()) {
    try {
      const std::string dir = store_.image_dir(s.uid);
      write_fillet_images(dir, u.fillet.image, r);
      for (const char* kind : {"overlay", "xray", "thickness", "pseudo_xray", "residual"}) {
        const std::string path = (fs::path(dir) / (std::string(kind) + ".png")).string();
        if (fs::exists(path)) store_.add_image(s.uid, kind, path);
      }
    } catch (const std::exception& e) {
      return failed("images of fillet " + std::to_string(s.uid) + ": " + e.what());
    }
  }
  u.images_stored = true;
  fillet_stored(s.lane, s.first_encoder);
  const int64_t t1 = steady_ns();
  store_time_.add((t1 - t0) / 1e6);
  if (u.last_arrival_ns) decision_.add((t1 - u.last_arrival_ns) / 1e6);
  hub_.publish(s);
  return true;
}

void Engine::retry_unsaved() {
  while (!unsaved_.empty() && save(unsaved_.front())) unsaved_.pop_front();
  std::lock_guard<std::mutex> lock(health_mu_);
  unsaved_count_ = unsaved_.size();
  if (unsaved_.empty()) store_failing_ = false;
  if (unsaved_.empty() && !store_error_.empty()) {
    std::fprintf(stderr, "rangexd: the store recovered\n");
    store_error_.clear();
  }
}

bool Engine::drain_and_stop(double timeout_s, OpenFillets open) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!stopping_) at_stop_ = open;
    stopping_ = true;
    paused_ = false;
  }
  stopping_flag_ = true;
  cv_.notify_all();
  {
    std::unique_lock<std::mutex> lock(done_mu_);
    if (timeout_s < 0)
      done_cv_.wait(lock, [&] { return done_; });
    else if (!done_cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                                [&] { return done_; }))
      return false;
  }
  if (worker_.joinable()) worker_.join();
  {
    std::lock_guard<std::mutex> lock(progress_mu_);
    progress_stop_ = true;
  }
  progress_cv_.notify_all();
  if (progress_.joinable()) {
    progress_.join();
    save_progress();  // every fillet decided: the counts as they end
  }
  return true;
}

std::vector<LaneState> Engine::lanes() {
  std::vector<LaneState> out;
  for (auto& l : lanes_) out.push_back(lane_state(l->id));
  return out;
}

LaneState Engine::lane_state(int id) {
  Lane& l = lane(id);
  LaneState s;
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    s.config = l.pending ? *l.pending : l.config;
    s.calibration_id = l.calibration_id;
    s.last_restart = l.last_restart;
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    s.fed = l.admission.fed();
    s.last_encoder = l.admission.last();
    s.accepted = l.accepted;
    if (l.last_line_ns) s.idle_ms = (steady_ns() - l.last_line_ns) / 1'000'000;
  }
  s.fillet_in_progress = l.in_progress;
  s.restarts = l.restarts;
  s.received = l.received;
  s.processed = l.processed;
  s.fillets = l.fillets;
  s.rejects = l.rejects;
  s.not_inspected = l.not_inspected;
  s.implied_frr = l.implied_frr;
  s.drift_fillets = l.drift_fillets;
  s.product_drift = l.product_drift;
  for (size_t i = 0; i < kRefusals; ++i)
    if (const uint64_t n = l.refused[i]) s.refused[std::string(refusal_name(Refusal(i)))] = n;
  for (size_t i = 0; i < kDropReasons; ++i)
    if (const uint64_t n = l.dropped[i]) s.dropped[std::string(drop_name(DropReason(i)))] = n;
  return s;
}

std::string Engine::calibration_of(int id) {
  Lane& l = lane(id);
  std::lock_guard<std::mutex> lock(ctl_mu_);
  return l.calibration_id;
}

StoredCalibration Engine::upload_calibration(int id, const std::string& cid,
                                             const std::string& yaml, const std::string& who,
                                             const std::string& report) {
  Lane& l = lane(id);
  if (cid.empty()) fail("a calibration needs an id");
  check_size("calibration '" + cid + "'", yaml.size(), kMaxCalibrationBytes);
  check_size("calibration '" + cid + "' report", report.size(), kMaxReportBytes);
  LaneConfig base;
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    base = l.config;
  }
  // Parse now: a malformed or non-finite calibration is refused at upload, naming the key.
  const LaneConfig parsed = apply_lane_calibration(base, yaml, "calibration '" + cid + "'");
  if (parsed.xray.pixels != l.pixels || parsed.frame_width != l.width ||
      parsed.frame_height != l.height)
    fail("calibration '", cid, "' changes the sensor sizes of lane ", id, "; that needs a restart");
  const ReportStatus rs = check_calibration_report(report);
  if (rs.present && !rs.passed && rs.why.rfind("the report cannot be read", 0) == 0)
    fail("calibration '", cid, "': ", rs.why);
  StoredCalibration c{id, cid, yaml, now_ns(), false, report};
  store_.add_calibration(c);
  store_.audit(who, "calibration.upload",
               "lane " + std::to_string(id) + " id " + cid + " report " +
                   (rs.passed    ? "passed"
                    : rs.present ? "failed"
                                 : "missing"));
  return c;
}

bool Engine::activate_calibration(int id, const std::string& cid, const std::string& who,
                                  bool force) {
  Lane& l = lane(id);
  const auto c = store_.calibration(id, cid);
  if (!c) fail_not_found("lane ", id, " has no calibration '", cid, "'");
  const ReportStatus rs = check_calibration_report(c->report);
  if (!rs.passed && !force)
    throw FailedPrecondition(join("calibration '", cid, "' of lane ", id, " is not activated: ",
                                  rs.why, " (force the activation to override; it is audited)"));
  LaneConfig base = plant_.lane(id);
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    base.inspection = l.config.inspection;  // thresholds stay as they are
  }
  LaneConfig next = apply_lane_calibration(base, c->yaml, "calibration " + cid);
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    l.pending = std::move(next);
    l.pending_id = cid;
  }
  store_.set_active_calibration(id, cid);
  if (rs.passed)
    store_.audit(who, "calibration.activate", "lane " + std::to_string(id) + " id " + cid);
  else
    store_.audit(who, "calibration.activate.forced",
                 "lane " + std::to_string(id) + " id " + cid + ": " + rs.why);
  return true;
}

LaneConfig Engine::update_thresholds(int id, std::optional<double> z, std::optional<double> area,
                                     std::optional<double> floor, const std::string& who) {
  Lane& l = lane(id);
  auto check = [](const char* name, std::optional<double> v) {
    if (v && !(std::isfinite(*v) && *v > 0))
      fail(name, " must be a finite number > 0 (got ", *v, ")");
  };
  check("z_threshold", z);
  check("min_fragment_area_mm2", area);
  check("floor_mm", floor);
  LaneConfig next;
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    next = l.pending ? *l.pending : l.config;
    if (z) next.inspection.z_threshold = *z;
    if (area) next.inspection.min_fragment_area_mm2 = *area;
    if (floor) next.inspection.floor_mm = *floor;
    l.pending = next;
  }
  std::string detail = "lane " + std::to_string(id);
  if (z) detail += " z_threshold=" + std::to_string(*z);
  if (area) detail += " min_fragment_area_mm2=" + std::to_string(*area);
  if (floor) detail += " floor_mm=" + std::to_string(*floor);
  store_.audit(who, "lane.thresholds", detail);
  return next;
}

LaneState Engine::reset_lane(int id, const std::string& who, const std::string& reason) {
  Lane& l = lane(id);
  const std::string by = "encoder reset by " + (who.empty() ? std::string("unknown") : who) +
                         (reason.empty() ? "" : ": " + reason);
  {
    std::lock_guard<std::mutex> lock(mu_);
    l.admission.request_reset(by);
  }
  store_.audit(who, "lane.reset",
               "lane " + std::to_string(id) + (reason.empty() ? "" : " " + reason));
  return lane_state(id);
}

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
  {
    std::lock_guard<std::mutex> lock(health_mu_);
    if (!store_error_.empty()) {
      h.store_ok = false;
      h.reasons.push_back("store failed: " + store_error_ + " (" + std::to_string(unsaved_count_) +
                          " decisions waiting to be stored)");
    }
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
  s.store_errors = store_errors_;
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
  s.store = store_time_.summary();
  for (int k = 0; k < kStages; ++k)
    s.inspection_stages.emplace_back(inspect_stage_name(k), inspection_stage_[k].summary());
  s.decision = decision_.summary();
  s.health = health();
  s.backend = runner_->running();
  s.backend_note = runner_->note();
  s.batches = runner_->stats();
  return s;
}

}  // namespace rangex
