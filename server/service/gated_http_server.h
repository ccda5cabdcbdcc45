// cpp-httplib's server behind the HttpGate, plain or TLS: accepted connections go to the gate
// instead of straight to a pooled thread, and a worker serves one request whose head has
// arrived, through a stream that reads that head first and then the connection.
#pragma once
#include <httplib.h>

#include <memory>
#include <string>

#include "service/http_gate.h"

struct ssl_ctx_st;

namespace rangex {

class GatedHttpServer : public httplib::Server {
 public:
  // With tls (taken: freed with the server), every connection is TLS.
  explicit GatedHttpServer(GateOptions opt, ssl_ctx_st* tls = nullptr);
  ~GatedHttpServer() override;
  HttpGate& gate() { return *gate_; }
  // The connection the calling worker serves (-1 elsewhere): a handler may tune its socket.
  static int current_fd();

 private:
  bool process_and_close_socket(socket_t sock) override;
  bool serve(GateConnection& c, std::string& head);
  ssl_ctx_st* tls_;
  size_t max_body_;  // the gate's bound on a body it waits for
  std::unique_ptr<HttpGate> gate_;
};

}  // namespace rangex
