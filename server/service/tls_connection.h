// A TLS connection at the gate. Its socket is non-blocking from accept on: the handshake and
// the request head are read on the gate's thread step by step, so a client that sends its
// handshake a byte at a time holds no worker. A worker then reads and writes through the
// same SSL object, waiting with poll() up to the server's timeouts.
#pragma once
#include <string>

#include "service/gate_connection.h"

namespace rangex {

class TlsConnection : public GateConnection {
 public:
  TlsConnection(int fd, ssl_st* ssl);  // takes the SSL object
  ~TlsConnection() override;
  Head read_head(std::string& head, size_t max_head, size_t max_body) override;
  bool has_read_ahead() const override;
  void refuse(const std::string& answer) override;
  std::unique_ptr<httplib::Stream> stream(std::string& head, time_t read_s,
                                          time_t write_s) override;
  ssl_st* tls() const override { return ssl_; }

 private:
  ssl_st* ssl_;
  bool handshaken_ = false;
  std::string ahead_;                           // decrypted bytes not yet part of a request
  size_t max_head_ = 64 * 1024, max_body_ = 0;  // read_head's last limits
};

}  // namespace rangex
