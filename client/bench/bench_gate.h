// bench-server --plc: the line's gate. A simulated PLC (SimPlc) whose belts move with time
// at the feed rate, as a belt does whatever rangexd is doing, and the tally of what each
// fillet met at the gate: released in time, released too late, diverted.
#pragma once
#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include "core/plant_config.h"
#include "plc/plc_simulator.h"
#include "plc/plc_state.h"

namespace rangex::cli {

class BenchGate {
 public:
  // Points plant.plc at the simulated PLC (the default register map).
  BenchGate(PlantConfig& plant, double lines_per_s);
  ~BenchGate();
  // The lane's belt shows `first_encoder` now and runs on at the rate.
  void start_lane(int lane, int64_t first_encoder);
  // What the gate saw, beside rangexd's own counts; `decided`: fillets the store holds.
  // Returns the clean fillets diverted for lateness (released late, late, or unreleased).
  uint64_t report(const PlcStatus& rangexd, int64_t decided);

 private:
  struct Belt {
    int64_t first = 0;
    std::chrono::steady_clock::time_point t0;
  };
  PlcConfig cfg_;
  std::map<int, double> step_mm_;
  double rate_;
  std::unique_ptr<SimPlc> plc_;
  std::mutex mu_;
  std::map<int, Belt> belts_;
  std::atomic<bool> stop_{false};
  std::thread mover_;
};

}  // namespace rangex::cli
