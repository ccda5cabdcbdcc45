// A Modbus TCP connection to the PLC (libmodbus), as rangex's release writer uses it: writes
// of holding registers, each answered within the timeout or failed with the reason.
#pragma once
#include <cstdint>
#include <string>

#include "core/error.h"

namespace rangex {

// The PLC answered a write with a Modbus exception (an address its program does not map, a
// value it will not take, busy): the connection is sound and stays open.
class PlcRefusal : public Error {
 public:
  using Error::Error;
};

class ModbusLink {
 public:
  ModbusLink(const std::string& address, int unit_id, double timeout_ms);
  ~ModbusLink();
  ModbusLink(const ModbusLink&) = delete;
  ModbusLink& operator=(const ModbusLink&) = delete;

  // Connects (or reconnects); throws Error with the reason.
  void connect();
  bool connected() const { return connected_; }
  void close();
  // Writes `n` registers from `first` (FC16; FC6 for one). A refusal throws PlcRefusal; any
  // other failure (no answer in time, the connection gone, a garbled reply) closes the
  // connection and throws Error.
  void write(int first, const uint16_t* values, int n);

 private:
  std::string host_;
  int port_ = 502, unit_ = 1;
  double timeout_ms_;
  void* ctx_ = nullptr;  // modbus_t
  bool connected_ = false;
};

}  // namespace rangex
