// The way back of a decision: each fillet the inspectors decide is stored (its record, then
// its images, written whole), then published to the results hub, each lane's in order. While
// the store fails, decisions wait here in order and are retried (up to kMaxUnsaved; beyond,
// the oldest leaves memory, loudly, its lines still not durable); the engine hands new lines
// back meanwhile. Owns the store's writes of decisions, the image files and the hub.
//
// Thread-safe: its lock (in the engine's lock map) is held while calling the store
// and the hub, neither of which calls back; `stored` is called under it.
#pragma once
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>

#include "pipeline/lane_processor.h"
#include "service/latency_stats.h"
#include "service/results_hub.h"
#include "store/store.h"

namespace rangex {

class DecisionRecorder {
 public:
  // Unsaved decisions kept while the store fails.
  static constexpr size_t kMaxUnsaved = 4096;
  // Called once a decision is committed (its record, with its uid), before it is published.
  using Stored = std::function<void(const StoredFillet& record)>;

  DecisionRecorder(Store& store, ResultsHub& hub, bool images, Stored stored);

  // The record of a decided fillet: every field of its result, the calibration it was
  // measured with, decided now. The one mapping from a FilletResult to the store's record.
  static StoredFillet record_of(const FilletResult& r, const std::string& calibration);

  // Stores and publishes `fillet` after every decision still waiting, or keeps it waiting.
  // `last_arrival_ns`: the steady time its last line arrived (0: unknown), for the latency.
  void record(InspectedFillet&& fillet, const std::string& calibration, int64_t last_arrival_ns);
  // Retries the waiting decisions (an idle inspector calls it).
  void retry();
  // The store's last chance at a stop: retried for up to a second.
  void flush();

  // Any thread:
  bool failing() const { return failing_; }  // decisions cannot be stored now
  uint64_t errors() const { return errors_; }
  // The store's error and how many decisions wait ("" when it works).
  std::string error(size_t* waiting = nullptr) const;
  LatencyStats::Summary store_latency() const { return store_time_.summary(); }
  LatencyStats::Summary decision_latency() const { return decision_.summary(); }

 private:
  struct Unsaved {
    StoredFillet record;
    InspectedFillet fillet;
    int64_t last_arrival_ns = 0;
    bool images_staged = false;  // written whole to the store's staging folder
  };
  bool save(Unsaved& u);  // mu_
  void retry_locked();    // mu_
  bool failed(const std::string& what);

  Store& store_;
  ResultsHub& hub_;
  const bool images_;
  Stored stored_;
  std::mutex mu_;
  std::deque<Unsaved> unsaved_;
  std::atomic<bool> failing_{false};
  std::atomic<uint64_t> errors_{0};
  mutable std::mutex error_mu_;  // leaf
  std::string error_;
  size_t waiting_ = 0;
  LatencyStats store_time_, decision_;
};

}  // namespace rangex
