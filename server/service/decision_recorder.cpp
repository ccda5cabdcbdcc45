#include "service/decision_recorder.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "core/log.h"
#include "pipeline/fillet_images.h"
#include "rangex/v1/decision_names.h"
#include "service/steady_ns.h"

namespace fs = std::filesystem;

namespace rangex {

DecisionRecorder::DecisionRecorder(Store& store, ResultsHub& hub, bool images, Stored stored)
    : store_(store), hub_(hub), images_(images), stored_(std::move(stored)) {}

StoredFillet DecisionRecorder::record_of(const FilletResult& r, const std::string& calibration) {
  StoredFillet s;
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
  s.calibration_id = calibration;
  for (const auto* list : {&r.fragments, &r.air_pockets})
    for (const Blob& b : *list)
      s.fragments.push_back({list == &r.fragments ? "bone" : "air", b.x_mm, b.y_mm, b.area_mm2,
                             b.peak_z, b.attenuation_mm2, b.meat_mm, b.row0, b.row1, b.col0, b.col1,
                             b.bone_mg});
  return s;
}

void DecisionRecorder::record(InspectedFillet&& fillet, const std::string& calibration,
                              int64_t last_arrival_ns) {
  Unsaved u;
  u.record = record_of(fillet.result, calibration);
  u.fillet = std::move(fillet);
  u.last_arrival_ns = last_arrival_ns;
  // Decisions are published in order, each once it is stored.
  std::lock_guard<std::mutex> lock(mu_);
  retry_locked();
  if (!unsaved_.empty() || !save(u)) {
    if (unsaved_.size() >= kMaxUnsaved) {
      // Its lines stay not durable (still pending): the feeders resend them to a server that
      // can store the decision.
      log::error("decision_dropped_from_memory",
                 "the store has failed for {} decisions; no longer held: lane {} fillet {} ({}), "
                 "its lines are handed back",
                 unsaved_.size(), unsaved_.front().record.lane, unsaved_.front().record.lane_fillet,
                 unsaved_.front().record.decision);
      unsaved_.pop_front();
    }
    unsaved_.push_back(std::move(u));
  }
  std::lock_guard<std::mutex> e(error_mu_);
  waiting_ = unsaved_.size();
}

void DecisionRecorder::retry() {
  std::lock_guard<std::mutex> lock(mu_);
  retry_locked();
}

void DecisionRecorder::flush() {
  std::lock_guard<std::mutex> lock(mu_);
  for (int tries = 0; tries < 20 && !unsaved_.empty(); ++tries) {
    retry_locked();
    if (!unsaved_.empty()) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (!unsaved_.empty())
    log::error("decisions_not_stored", "{} decisions could not be stored before the stop",
               unsaved_.size());
}

std::string DecisionRecorder::error(size_t* waiting) const {
  std::lock_guard<std::mutex> lock(error_mu_);
  if (waiting) *waiting = waiting_;
  return error_;
}

bool DecisionRecorder::failed(const std::string& what) {
  ++errors_;
  failing_ = true;
  std::lock_guard<std::mutex> lock(error_mu_);
  if (error_.empty())
    log::error("store_failed", "the store failed: {}; decisions wait until it recovers", what);
  error_ = what;
  return false;
}

bool DecisionRecorder::save(Unsaved& u) {
  const int64_t t0 = steady_ns();
  StoredFillet& s = u.record;
  const FilletResult& r = u.fillet.result;
  // The images are part of the decision: written whole (each renamed into place), then
  // stored with it in one transaction, or retried with it. The decision is durable and
  // published after them.
  std::string staged;
  if (images_ && r.decision != Decision::kPass && !u.fillet.image.mask.empty()) {
    try {
      staged = store_.staging_dir(s);
      // Written whole by this server once, they wait there while the store fails.
      if (!u.images_staged || !fs::exists(staged)) {
        u.images_staged = false;
        fs::remove_all(staged);
        write_fillet_images(staged, u.fillet.image, r);
        u.images_staged = true;
      }
    } catch (const std::exception& e) {
      return failed("images of lane " + std::to_string(s.lane) + " fillet " +
                    std::to_string(s.lane_fillet) + ": " + e.what());
    }
  }
  try {
    s.uid = store_.add_fillet(s, staged);
  } catch (const std::exception& e) {
    return failed(e.what());
  }
  if (stored_) stored_(s);
  const int64_t t1 = steady_ns();
  store_time_.add((t1 - t0) / 1e6);
  if (u.last_arrival_ns) decision_.add((t1 - u.last_arrival_ns) / 1e6);
  hub_.publish(s);
  return true;
}

void DecisionRecorder::retry_locked() {
  while (!unsaved_.empty() && save(unsaved_.front())) unsaved_.pop_front();
  std::lock_guard<std::mutex> lock(error_mu_);
  waiting_ = unsaved_.size();
  if (unsaved_.empty()) failing_ = false;
  if (unsaved_.empty() && !error_.empty()) {
    log::info("store_recovered", "the store recovered");
    error_.clear();
  }
}

}  // namespace rangex
