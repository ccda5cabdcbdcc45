// The engine's lanes, threads and stop (engine.h); its other jobs each have a file:
// admission (engine_admission.cpp), the batching worker (engine_worker.cpp), the inspectors
// (engine_inspectors.cpp), lane control (engine_control.cpp), health and statistics
// (engine_health.cpp), durability (engine_progress.cpp), live learning
// (engine_learning.cpp); decisions go back through the DecisionRecorder.
#include "service/engine.h"

#include <random>
#include <thread>

#include "core/error.h"
#include "service/steady_ns.h"

namespace rangex {

Engine::Lane::Lane(const LaneConfig& c, const EngineOptions& o, size_t slot)
    : id(c.id),
      slot(slot),
      width(c.frame_width),
      height(c.frame_height),
      pixels(c.xray.pixels),
      energies(c.xray.energies),
      admission(c.id, o.dedup_window, o.auto_reset),
      config(c) {}

Engine::Engine(const PlantConfig& plant, Store& store, ResultsHub& hub, EngineOptions opt)
    : plant_(plant),
      store_(store),
      opt_(std::move(opt)),
      recorder_(store, hub, opt_.images,
                [this](const StoredFillet& s) {
                  fillet_stored(s.lane, s.first_encoder);
                  verifications_->decided(s);
                  if (opt_.on_decided) opt_.on_decided(s);
                }),
      queue_(plant_.lanes.size()) {
  verifications_ = std::make_unique<Verifications>(plant_, store_);
  shift_ = std::make_unique<ShiftRecorder>(
      plant_, store_.dir(), opt_.store_reserve_mb,
      [this](const std::string& who, const std::string& what, const std::string& detail) {
        store_.audit(who, what, detail);
      });
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
    l->xray.resize(size_t(l->pixels) * size_t(l->energies));
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

}  // namespace rangex
