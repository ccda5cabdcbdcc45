#include "service/engine.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "core/error.h"
#include "pipeline/fillet_images.h"

namespace fs = std::filesystem;

namespace rangex {

namespace {
int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

Engine::Engine(const PlantConfig& plant, Store& store, ResultsHub& hub, EngineOptions opt)
    : plant_(plant), store_(store), hub_(hub), opt_(opt) {
  counters_.queue_capacity = int(opt_.queue_capacity);
  for (const LaneConfig& lc : plant_.lanes) {
    auto l = std::make_unique<Lane>();
    l->id = lc.id;
    l->width = lc.frame_width;
    l->height = lc.frame_height;
    l->pixels = lc.xray.pixels;
    l->config = lc;
    l->calibration_id = plant_.calibration_id;
    // A calibration activated before a restart is active again.
    for (const StoredCalibration& c : store_.calibrations(lc.id))
      if (c.active) {
        l->config = apply_lane_calibration(lc, c.yaml, "calibration " + c.id);
        l->calibration_id = c.id;
      }
    Lane* raw = l.get();
    l->proc = std::make_unique<LaneProcessor>(
        l->config, LaneProcessorOptions{opt_.threads, false, opt_.images},
        [this, raw](InspectedFillet&& f) { on_fillet(*raw, std::move(f)); });
    lanes_.push_back(std::move(l));
  }
  worker_ = std::thread([this] { worker(); });
}

Engine::~Engine() {
  drain_and_stop();
}

Engine::Lane& Engine::lane(int id) {
  for (auto& l : lanes_)
    if (l->id == id) return *l;
  fail("unknown lane ", id, " (the plant has lanes ", plant_.lanes.front().id, "..",
       plant_.lanes.back().id, ")");
}

void Engine::drop(const std::string& reason) {
  std::lock_guard<std::mutex> lock(smu_);
  ++counters_.drops[reason];
}

Engine::Verdict Engine::submit(IncomingLine&& line) {
  Verdict v;
  {
    std::lock_guard<std::mutex> lock(smu_);
    ++counters_.received;
  }
  auto refuse = [&](const char* code, std::string message) {
    drop(code);
    v.accepted = false;
    v.code = code;
    v.message = std::move(message);
    std::lock_guard<std::mutex> lock(qmu_);
    v.credit = int(opt_.queue_capacity - std::min(queue_.size(), opt_.queue_capacity));
    return v;
  };
  Lane* l = nullptr;
  for (auto& x : lanes_)
    if (x->id == line.lane) l = x.get();
  if (!l) return refuse("UNKNOWN_LANE", "unknown lane " + std::to_string(line.lane));
  const size_t frame = size_t(l->width) * l->height;
  const size_t limit = 4 * (2 * frame + size_t(l->pixels) * 2);
  if (line.cam0.size() + line.cam1.size() + line.xray.size() > limit)
    return refuse("OVERSIZED",
                  "line of " +
                      std::to_string(line.cam0.size() + line.cam1.size() + line.xray.size()) +
                      " bytes; lane " + std::to_string(l->id) + " lines are " +
                      std::to_string(2 * frame + size_t(l->pixels) * 2) + " bytes");
  if (line.cam0.size() != frame || line.cam1.size() != frame)
    return refuse("WRONG_FRAME_SIZE",
                  "camera frames of " + std::to_string(line.cam0.size()) + " and " +
                      std::to_string(line.cam1.size()) + " bytes; lane " + std::to_string(l->id) +
                      " expects " + std::to_string(l->width) + "x" + std::to_string(l->height) +
                      " = " + std::to_string(frame));
  if (line.xray.size() != size_t(l->pixels) * 2)
    return refuse("WRONG_XRAY_SIZE", "X-ray line of " + std::to_string(line.xray.size()) +
                                         " bytes; lane " + std::to_string(l->id) + " expects " +
                                         std::to_string(l->pixels) + " 16-bit pixels");
  {
    std::lock_guard<std::mutex> lock(l->mu);
    if (!line.calibration_id.empty() && line.calibration_id != l->calibration_id)
      return refuse("CALIBRATION_MISMATCH", "line made with calibration '" + line.calibration_id +
                                                "' but lane " + std::to_string(l->id) + " runs '" +
                                                l->calibration_id + "'");
    if (line.encoder == l->last_encoder)
      return refuse("DUPLICATE_LINE", "encoder " + std::to_string(line.encoder) + " of lane " +
                                          std::to_string(l->id) + " was already received");
    if (line.encoder < l->last_encoder)
      return refuse("ENCODER_BACKWARDS", "encoder " + std::to_string(line.encoder) + " after " +
                                             std::to_string(l->last_encoder) + " on lane " +
                                             std::to_string(l->id));
  }
  std::unique_lock<std::mutex> q(qmu_);
  if (stopping_) {
    q.unlock();
    return refuse("SHUTTING_DOWN", "the server is shutting down");
  }
  if (queue_.size() >= opt_.queue_capacity) {
    q.unlock();
    // The line is lost: its encoder stays unaccounted, so the assembly sees a gap and
    // fails the fillets around it safe.
    return refuse("OVERLOAD",
                  "queue full (" + std::to_string(opt_.queue_capacity) +
                      " lines); line dropped, its fillet will be rejected as not inspected");
  }
  {
    std::lock_guard<std::mutex> lock(l->mu);
    l->last_encoder = line.encoder;
    l->arrivals[line.encoder] = steady_ns();
  }
  queue_.push_back({std::move(line), steady_ns()});
  v.accepted = true;
  v.credit = int(opt_.queue_capacity - queue_.size());
  q.unlock();
  qcv_.notify_one();
  return v;
}

void Engine::pause(bool paused) {
  {
    std::lock_guard<std::mutex> lock(qmu_);
    paused_ = paused;
  }
  qcv_.notify_all();
}

void Engine::worker() {
  std::vector<Queued> batch;
  while (true) {
    {
      std::unique_lock<std::mutex> lock(qmu_);
      qcv_.wait(lock, [&] { return (!queue_.empty() && !paused_) || stopping_; });
      if (!stopping_ && !paused_ && int(queue_.size()) < opt_.batch_lines) {
        // Give a partial batch a moment to fill.
        qcv_.wait_for(lock, std::chrono::milliseconds(opt_.batch_wait_ms),
                      [&] { return int(queue_.size()) >= opt_.batch_lines || stopping_; });
      }
      if (queue_.empty()) {
        if (stopping_) break;
        continue;
      }
      if (paused_ && !stopping_) continue;  // paused while waiting for a batch to fill
      const size_t n = std::min(queue_.size(), size_t(opt_.batch_lines));
      batch.clear();
      for (size_t i = 0; i < n; ++i) {
        batch.push_back(std::move(queue_.front()));
        queue_.pop_front();
      }
    }
    process(batch);
  }
  for (auto& l : lanes_) l->proc->finish();
}

void Engine::process(std::vector<Queued>& batch) {
  const int64_t start = steady_ns();
  for (const Queued& q : batch) queue_wait_.add((start - q.arrived_ns) / 1e6);
  for (auto& lp : lanes_) {
    Lane& l = *lp;
    std::vector<const Queued*> mine;
    for (const Queued& q : batch)
      if (q.line.lane == l.id) mine.push_back(&q);
    // A pending calibration or threshold change takes over at a batch boundary at which the
    // lane has no fillet in progress. While one is pending, the lane's share is pushed line
    // by line, so that every line boundary is such a candidate (quiet stretches between
    // close fillets can be shorter than a batch).
    auto apply_pending = [&] {
      std::lock_guard<std::mutex> lock(l.mu);
      if (!l.pending || !l.proc->quiet()) return;
      l.proc->reconfigure(*l.pending);
      l.config = *l.pending;
      if (!l.pending_id.empty()) l.calibration_id = l.pending_id;
      l.pending.reset();
      l.pending_id.clear();
    };
    auto has_pending = [&] {
      std::lock_guard<std::mutex> lock(l.mu);
      return l.pending.has_value();
    };
    apply_pending();
    if (mine.empty()) continue;
    const size_t frame = size_t(l.width) * l.height;
    std::vector<uint8_t> frames(frame * 2 * mine.size());
    std::vector<uint16_t> xray(size_t(l.pixels) * mine.size());
    std::vector<int64_t> enc(mine.size());
    for (size_t k = 0; k < mine.size(); ++k) {
      std::memcpy(&frames[frame * 2 * k], mine[k]->line.cam0.data(), frame);
      std::memcpy(&frames[frame * (2 * k + 1)], mine[k]->line.cam1.data(), frame);
      std::memcpy(&xray[size_t(l.pixels) * k], mine[k]->line.xray.data(), size_t(l.pixels) * 2);
      enc[k] = mine[k]->line.encoder;
    }
    const auto t0 = steady_ns();
    const double insp_before = l.proc->inspection_seconds();
    if (!has_pending()) {
      l.proc->push(int(mine.size()), frames.data(), xray.data(), enc.data());
    } else {
      for (size_t k = 0; k < mine.size(); ++k) {
        apply_pending();
        l.proc->push(1, &frames[frame * 2 * k], &xray[size_t(l.pixels) * k], &enc[k]);
      }
    }
    const double insp = l.proc->inspection_seconds() - insp_before;
    pipeline_.add((steady_ns() - t0) / 1e6 - insp * 1e3);
  }
  std::lock_guard<std::mutex> lock(smu_);
  counters_.processed += batch.size();
  rate_.emplace_back(steady_ns(), counters_.processed);
  while (rate_.size() > 2 && rate_.front().first < rate_.back().first - 2'000'000'000)
    rate_.pop_front();
}

void Engine::on_fillet(Lane& l, InspectedFillet&& f) {
  const FilletResult& r = f.result;
  inspection_.add(f.inspect_ms);
  StoredFillet s;
  s.lane = r.lane;
  s.lane_fillet = r.id;
  s.first_encoder = r.first_encoder;
  s.rows = r.rows;
  s.decision = std::string(decision_name(r.decision));
  s.reason = r.reason;
  s.beta0 = r.fit.beta0;
  s.beta1 = r.fit.beta1;
  s.resid_mean_dn = r.resid_mean_dn;
  s.resid_std_dn = r.resid_std_dn;
  s.belt_y0_mm = r.y0_mm;
  s.decided_ns = now_ns();
  {
    std::lock_guard<std::mutex> lock(l.mu);
    s.calibration_id = l.calibration_id;
  }
  for (const auto* list : {&r.fragments, &r.air_pockets})
    for (const Blob& b : *list)
      s.fragments.push_back({list == &r.fragments ? "bone" : "air", b.x_mm, b.y_mm, b.area_mm2,
                             b.peak_z, b.attenuation_mm2});
  s.uid = store_.add_fillet(s);
  if (opt_.images && r.decision != Decision::kPass && !f.image.mask.empty()) {
    const std::string dir = store_.image_dir(s.uid);
    write_fillet_images(dir, f.image, r);
    for (const char* kind : {"overlay", "xray", "thickness", "pseudo_xray", "residual"}) {
      const std::string path = (fs::path(dir) / (std::string(kind) + ".png")).string();
      if (fs::exists(path)) store_.add_image(s.uid, kind, path);
    }
  }
  // Decision latency: from the arrival of the fillet's last line to now.
  {
    std::lock_guard<std::mutex> lock(l.mu);
    const int64_t last = r.first_encoder + r.rows - 1;
    auto it = l.arrivals.upper_bound(last);
    if (it != l.arrivals.begin()) {
      --it;
      decision_.add((steady_ns() - it->second) / 1e6);
    }
    // Arrival times older than this fillet are no longer needed.
    l.arrivals.erase(l.arrivals.begin(), l.arrivals.lower_bound(r.first_encoder));
  }
  {
    std::lock_guard<std::mutex> lock(smu_);
    ++counters_.fillets;
    counters_.rejects += r.decision == Decision::kReject;
    counters_.not_inspected += r.decision == Decision::kNotInspected;
  }
  hub_.publish(s);
}

void Engine::drain_and_stop() {
  {
    std::lock_guard<std::mutex> lock(qmu_);
    if (stopped_) return;
    stopping_ = true;
    paused_ = false;
    stopped_ = true;
  }
  qcv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

std::vector<LaneConfig> Engine::lanes() {
  std::vector<LaneConfig> out;
  for (auto& l : lanes_) {
    std::lock_guard<std::mutex> lock(l->mu);
    out.push_back(l->pending ? *l->pending : l->config);
  }
  return out;
}

std::string Engine::calibration_of(int id) {
  Lane& l = lane(id);
  std::lock_guard<std::mutex> lock(l.mu);
  return l.calibration_id;
}

StoredCalibration Engine::upload_calibration(int id, const std::string& cid,
                                             const std::string& yaml, const std::string& who) {
  Lane& l = lane(id);
  if (cid.empty()) fail("a calibration needs an id");
  LaneConfig base;
  {
    std::lock_guard<std::mutex> lock(l.mu);
    base = l.config;
  }
  // Parse now: a malformed or non-finite calibration is refused at upload, naming the key.
  const LaneConfig parsed = apply_lane_calibration(base, yaml, "calibration '" + cid + "'");
  if (parsed.xray.pixels != l.pixels || parsed.frame_width != l.width ||
      parsed.frame_height != l.height)
    fail("calibration '", cid, "' changes the sensor sizes of lane ", id, "; that needs a restart");
  StoredCalibration c{id, cid, yaml, now_ns(), false};
  store_.add_calibration(c);
  store_.audit(who, "calibration.upload", "lane " + std::to_string(id) + " id " + cid);
  return c;
}

bool Engine::activate_calibration(int id, const std::string& cid, const std::string& who) {
  Lane& l = lane(id);
  const auto c = store_.calibration(id, cid);
  if (!c) fail("lane ", id, " has no calibration '", cid, "'");
  LaneConfig base = plant_.lane(id);
  {
    std::lock_guard<std::mutex> lock(l.mu);
    base.inspection = l.config.inspection;  // thresholds stay as they are
    l.pending = apply_lane_calibration(base, c->yaml, "calibration " + cid);
    l.pending_id = cid;
  }
  store_.set_active_calibration(id, cid);
  store_.audit(who, "calibration.activate", "lane " + std::to_string(id) + " id " + cid);
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
    std::lock_guard<std::mutex> lock(l.mu);
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

EngineStats Engine::stats() {
  EngineStats s;
  {
    std::lock_guard<std::mutex> lock(smu_);
    s = counters_;
    if (rate_.size() >= 2) {
      const double dt = (rate_.back().first - rate_.front().first) / 1e9;
      if (dt > 0) s.lines_per_second = double(rate_.back().second - rate_.front().second) / dt;
    }
  }
  {
    std::lock_guard<std::mutex> lock(qmu_);
    s.queue_depth = int(queue_.size());
  }
  s.queue_capacity = int(opt_.queue_capacity);
  s.queue_wait = queue_wait_.summary();
  s.pipeline = pipeline_.summary();
  s.inspection = inspection_.summary();
  s.decision = decision_.summary();
  return s;
}

}  // namespace rangex
