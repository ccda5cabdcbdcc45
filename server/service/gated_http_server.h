// cpp-httplib's server behind the HttpGate (plain HTTP): accepted connections go to the gate
// instead of straight to a pooled thread, and a worker serves one request whose head has
// arrived, through a Stream that reads that head first and then the socket.
#pragma once
#include <httplib.h>

#include <memory>
#include <string>

#include "service/http_gate.h"

namespace rangex {

class GatedHttpServer : public httplib::Server {
 public:
  explicit GatedHttpServer(GateOptions opt);
  ~GatedHttpServer() override;
  HttpGate& gate() { return *gate_; }
  // The connection the calling worker serves (-1 elsewhere): a handler may tune its socket.
  static int current_fd();

 private:
  bool process_and_close_socket(socket_t sock) override;
  bool serve(int fd, std::string& head);
  std::unique_ptr<HttpGate> gate_;
};

}  // namespace rangex
