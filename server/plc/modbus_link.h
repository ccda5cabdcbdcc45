// A Modbus TCP connection to the PLC (libmodbus), as rangex's release writer uses it: writes
// of holding registers, each answered within the timeout or failed with the reason.
#pragma once
#include <cstdint>
#include <string>

namespace rangex {

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
  // Writes `n` registers from `first` (FC16; FC6 for one); throws Error and closes on failure.
  void write(int first, const uint16_t* values, int n);

 private:
  std::string host_;
  int port_ = 502, unit_ = 1;
  double timeout_ms_;
  void* ctx_ = nullptr;  // modbus_t
  bool connected_ = false;
};

}  // namespace rangex
