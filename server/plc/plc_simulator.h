// A simulated PLC: a Modbus TCP server (libmodbus) on loopback holding the registers rangex
// writes, reading its ring of releases as a PLC program would (docs/plc.md), each release
// noted with where the lane's belt was when it arrived; whoever runs it moves the belts. For
// the tests, the bench, the demo and an integrator's dry run (`rangexctl plc-sim`); and the
// reference for a PLC program's reading of the ring.
#pragma once
#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "core/plc_config.h"
#include "plc/release_registers.h"

namespace rangex {

class SimPlc {
 public:
  // Listens on 127.0.0.1:`port` (0: a free port) with cfg's register map.
  explicit SimPlc(const PlcConfig& cfg, int port = 0);
  ~SimPlc();
  int port() const { return port_; }
  // Stops answering (connections closed, nothing listening), and starts again: a restarted
  // PLC has lost its registers.
  void stop();
  void start();
  // Faults of a real PLC, for the tests and an integrator's dry run. A PLC program that maps
  // fewer holding registers answers a write past them with Modbus exception 2 (illegal data
  // address); one that stops answering (a stopped CPU behind its communication module, a
  // gateway with no route) takes each request and replies to none. Both take effect at once.
  void set_registers(int count);  // 1..65536 (65536 when made)
  void set_silent(bool silent);

  void belt(int lane, int64_t count);  // where the lane's encoder is now
  struct Received {
    Release release;
    uint16_t sequence = 0;
    int64_t belt = INT64_MIN;  // the lane's belt count when it arrived
  };
  std::vector<Received> received() const;
  uint16_t heartbeat() const;
  PackMl lane_state(int lane) const;
  StateReason lane_reason(int lane) const;

 private:
  void serve();
  void scan();  // new slots in the ring (under mu_)

  PlcConfig cfg_;
  int port_ = 0;
  mutable std::mutex mu_;
  std::vector<uint16_t> regs_;
  std::vector<uint16_t> seen_;  // the sequence last taken from each slot
  std::map<int, int64_t> belt_;
  std::vector<Received> received_;
  std::atomic<bool> stop_{false}, serving_{false}, silent_{false};
  std::atomic<int> registers_{65536};
  std::thread thread_;
};

}  // namespace rangex
