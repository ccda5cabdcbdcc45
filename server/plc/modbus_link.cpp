#include "plc/modbus_link.h"

#include <modbus/modbus.h>

#include <cerrno>

#include "core/error.h"

namespace rangex {

ModbusLink::ModbusLink(const std::string& address, int unit_id, double timeout_ms)
    : unit_(unit_id), timeout_ms_(timeout_ms) {
  const auto colon = address.rfind(':');
  if (colon == std::string::npos) fail("PLC address '", address, "' is not host:port");
  host_ = address.substr(0, colon);
  port_ = std::stoi(address.substr(colon + 1));
}

ModbusLink::~ModbusLink() {
  close();
  if (ctx_) modbus_free(static_cast<modbus_t*>(ctx_));
}

void ModbusLink::connect() {
  close();
  if (!ctx_) {
    ctx_ = modbus_new_tcp(host_.c_str(), port_);
    if (!ctx_) fail("PLC ", host_, ":", port_, ": ", modbus_strerror(errno));
  }
  auto* m = static_cast<modbus_t*>(ctx_);
  modbus_set_slave(m, unit_);
  const auto us = uint32_t(timeout_ms_ * 1000);
  modbus_set_response_timeout(m, us / 1000000, us % 1000000);
  if (modbus_connect(m) != 0)
    fail("PLC ", host_, ":", port_, " unreachable: ", modbus_strerror(errno));
  connected_ = true;
}

void ModbusLink::close() {
  if (ctx_ && connected_) modbus_close(static_cast<modbus_t*>(ctx_));
  connected_ = false;
}

void ModbusLink::write(int first, const uint16_t* values, int n) {
  if (!connected_) fail("PLC ", host_, ":", port_, " is not connected");
  auto* m = static_cast<modbus_t*>(ctx_);
  const int rc = n == 1 ? modbus_write_register(m, first, values[0])
                        : modbus_write_registers(m, first, n, values);
  if (rc != n) {
    const int err = errno;
    const std::string why = modbus_strerror(err);
    if (err >= EMBXILFUN && err <= EMBXGTAR)
      throw PlcRefusal(join("PLC ", host_, ":", port_, " refuses registers ", first, "..",
                            first + n - 1, ": ", why));
    close();
    fail("PLC ", host_, ":", port_, ": writing registers ", first, "..", first + n - 1, ": ", why);
  }
}

}  // namespace rangex
