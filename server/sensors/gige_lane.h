// A lane fed by its own sensors: a thread per device (two laser cameras, the X-ray detector)
// takes its frames and the joiner makes them lines for the sink (the engine). A device that
// stops answering ends the lane's open fillets as not inspected (sink.lost, with the reason)
// and is reconnected with backoff; one that refuses its configuration is retried the same way,
// its refusal shown. Counters and states are read by ListLanes, /metrics and the dashboard.
#pragma once
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "core/incoming_line.h"
#include "core/lane_config.h"
#include "sensors/frame_counts.h"
#include "sensors/gige_device.h"
#include "sensors/line_joiner.h"
#include "sensors/sensor_state.h"

namespace rangex {

struct LaneSink {
  // A complete line; returns whether the engine accepted it.
  std::function<bool(IncomingLine&&)> line;
  // A device dropped off: the lane's open fillets end as not inspected for `why`.
  std::function<void(const std::string& why)> lost;
};

struct SensorOptions {
  int buffers = 128;            // receive buffers per device
  double backoff_min_s = 0.25;  // first wait before reconnecting, doubled up to the max
  double backoff_max_s = 8;
  double silence_probe_s = 1.0;  // a silent device is asked whether it still answers
};

class GigeLane {
 public:
  GigeLane(const LaneConfig& lane, LaneSink sink, SensorOptions opt = {});
  ~GigeLane();
  // Stops the devices (their threads joined); the state stays readable.
  void stop();
  LaneSensors state() const;

 private:
  void run_device(int index);
  // A device that keeps its own count delivered its first frame (under count_mu_).
  void note_first_id(int index, const std::string& who, uint64_t id);
  void set(int index, const std::function<void(SensorState&)>& change);
  bool sleep_for(double seconds);  // false when stopping

  const int lane_;
  const LaneConfig config_;
  LaneSink sink_;
  const SensorOptions opt_;
  LineJoiner joiner_;
  std::mutex count_mu_;  // start_ids_, and a frame's count with its add to the joiner
  LaneStartIds start_ids_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> refused_{0};
  mutable std::mutex mu_;  // states_
  std::condition_variable wake_;
  std::vector<SensorState> states_;
  std::vector<std::thread> threads_;
};

}  // namespace rangex
