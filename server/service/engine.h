// The server's processing core: validated lines from every lane go into one bounded queue;
// a worker takes them in batches (bounded by count and by time), runs each lane's share
// through its LaneProcessor, and every fillet decided is stored and published. Calibration
// and threshold changes wait for a batch boundary at which the lane has no fillet in
// progress, so no fillet is ever measured half with one calibration and half with another.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/plant_config.h"
#include "pipeline/lane_processor.h"
#include "service/latency_stats.h"
#include "service/results_hub.h"
#include "service/store.h"

namespace rangex {

struct IncomingLine {
  int lane = 0;
  int64_t encoder = 0;
  std::string cam0, cam1, xray;  // raw bytes as received
  std::string calibration_id;    // what the sender believes active; empty: not checked
};

struct EngineOptions {
  size_t queue_capacity = 2048;  // lines waiting for the worker, all lanes together
  int batch_lines = 64;
  int batch_wait_ms = 10;  // a partial batch goes after this long
  int threads = 1;         // stripe-stage workers
  bool images = true;      // store images of rejected / not inspected fillets
};

struct EngineStats {
  uint64_t received = 0, processed = 0, fillets = 0, rejects = 0, not_inspected = 0;
  std::map<std::string, uint64_t> drops;  // by reason
  double lines_per_second = 0;
  int queue_depth = 0, queue_capacity = 0;
  LatencyStats::Summary queue_wait, pipeline, inspection, decision;
};

class Engine {
 public:
  Engine(const PlantConfig& plant, Store& store, ResultsHub& hub, EngineOptions opt);
  ~Engine();

  struct Verdict {
    bool accepted = false;
    std::string code, message;
    int credit = 0;
  };
  // Validates and queues one line; never throws for bad input (the verdict says why).
  Verdict submit(IncomingLine&& line);
  // Graceful stop: refuse new lines, process every queued one, close open fillets.
  void drain_and_stop();
  // Holds the worker (tests use it to fill the queue and see overload handled).
  void pause(bool paused);

  std::vector<LaneConfig> lanes();
  std::string calibration_of(int lane);
  StoredCalibration upload_calibration(int lane, const std::string& id, const std::string& yaml,
                                       const std::string& who);
  bool activate_calibration(int lane, const std::string& id, const std::string& who);
  LaneConfig update_thresholds(int lane, std::optional<double> z, std::optional<double> area,
                               std::optional<double> floor, const std::string& who);
  EngineStats stats();
  const PlantConfig& plant() const { return plant_; }

 private:
  struct Lane {
    int id = 0;
    int width = 0, height = 0, pixels = 0;  // fixed for the server's life
    std::unique_ptr<LaneProcessor> proc;    // worker thread only
    std::mutex mu;                          // guards what follows
    LaneConfig config;                      // current (what the processor runs)
    std::string calibration_id;
    std::optional<LaneConfig> pending;
    std::string pending_id;
    int64_t last_encoder = INT64_MIN;
    std::map<int64_t, int64_t> arrivals;  // encoder -> steady ns, for the decision latency
  };
  struct Queued {
    IncomingLine line;
    int64_t arrived_ns;
  };

  void worker();
  void process(std::vector<Queued>& batch);
  void on_fillet(Lane& lane, InspectedFillet&& f);
  void drop(const std::string& reason);
  Lane& lane(int id);

  PlantConfig plant_;
  Store& store_;
  ResultsHub& hub_;
  EngineOptions opt_;
  std::vector<std::unique_ptr<Lane>> lanes_;

  std::mutex qmu_;
  std::condition_variable qcv_;
  std::deque<Queued> queue_;
  bool stopping_ = false, stopped_ = false, paused_ = false;
  std::thread worker_;

  std::mutex smu_;
  EngineStats counters_;
  std::deque<std::pair<int64_t, uint64_t>> rate_;  // (steady ns, processed) samples
  LatencyStats queue_wait_, pipeline_, inspection_, decision_;
};

}  // namespace rangex
