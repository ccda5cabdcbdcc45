// A plain-HTTP connection at the gate: heads are peeked at and taken off the socket exactly,
// so a body and the next request stay in the socket.
#pragma once
#include "service/gate_connection.h"

namespace rangex {

class PlainConnection : public GateConnection {
 public:
  using GateConnection::GateConnection;
  Head read_head(std::string& head, size_t max_head, size_t max_body) override;
  void refuse(const std::string& answer) override;
  std::unique_ptr<httplib::Stream> stream(std::string& head, time_t read_s,
                                          time_t write_s) override;
};

}  // namespace rangex
