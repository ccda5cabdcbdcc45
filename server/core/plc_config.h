// The line's PLC (plant.yaml `plc:`): rangex releases each fillet it has inspected and found
// clean by writing it into a ring of holding registers over Modbus TCP; the PLC diverts every
// fillet not released by the time it reaches the gate. The register map is docs/plc.md's.
#pragma once
#include <string>

namespace rangex {

struct PlcConfig {
  std::string address;  // host:port of the PLC's Modbus TCP server; empty: no PLC
  int unit_id = 1;
  int heartbeat_register = 0;  // counts up every heartbeat_ms while rangexd is alive
  int ring_head_register = 1;  // the slot written last
  int lane_state_base = 10;    // lane L (0..63): base + 2L (PackML state), base + 2L + 1 (reason)
  int ring_base = 200;         // slot s: ring_base + 8 s .. + 7
  int ring_slots = 64;
  static constexpr int kMaxLanes = 64;
  double reject_station_mm = 1000;  // X-ray plane to the gate, along the belt
  double margin_mm = 20;            // a release must reach the PLC this far ahead of the gate
  double heartbeat_ms = 100;
  double timeout_ms = 250;  // a Modbus request without an answer by then fails

  bool enabled() const { return !address.empty(); }
  int ring_end() const { return ring_base + 8 * ring_slots; }  // one past the last register
};

}  // namespace rangex
