// The PLC link as statistics, /metrics and the dashboard show it: plain values.
#pragma once
#include <cstdint>
#include <map>
#include <string>

namespace rangex {

struct PlcStatus {
  bool enabled = false;
  std::string address;
  bool connected = false;
  std::string error;  // why it is not connected ("" when it is)
  // Connected, the registers the PLC answers with a Modbus exception: which, and what that
  // costs ("" when it takes every write).
  std::string refused;
  uint64_t released = 0;    // clean fillets released before their deadline
  uint64_t diverted = 0;    // rejected and not-inspected fillets sent (the PLC diverts them)
  uint64_t late = 0;        // clean fillets decided after their deadline: diverted
  uint64_t unreleased = 0;  // clean fillets not sent by their deadline (PLC unreachable)
  uint64_t pending = 0;     // waiting to be sent
  uint64_t reconnects = 0;
  double least_spare_ms = -1;  // the smallest time to spare of a release sent (-1: none yet)
  std::map<int, std::string> lane_states;  // PackML state as last written, by lane
};

}  // namespace rangex
