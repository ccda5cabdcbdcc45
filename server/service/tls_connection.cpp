#include "service/tls_connection.h"

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <poll.h>

#include <algorithm>
#include <climits>
#include <cstring>

#include "service/gate_stream.h"
#include "service/request_end.h"

namespace rangex {

namespace {

int clamp_int(size_t n) {
  return int(std::min<size_t>(n, INT_MAX));
}

class TlsStream : public GateStream {
 public:
  TlsStream(int fd, SSL* ssl, std::string& ahead, std::string& head, time_t read_s, time_t write_s)
      : GateStream(fd, head, read_s, write_s), ssl_(ssl), ahead_(ahead) {}
  ssize_t write(const char* ptr, size_t size) override {
    while (true) {
      ERR_clear_error();
      const int r = SSL_write(ssl_, ptr, clamp_int(size));
      if (r > 0) return r;
      if (!wait(SSL_get_error(ssl_, r))) return -1;
    }
  }

 protected:
  ssize_t read_more(char* ptr, size_t size) override {
    if (!ahead_.empty()) {
      const size_t n = std::min(size, ahead_.size());
      std::memcpy(ptr, ahead_.data(), n);
      ahead_.erase(0, n);
      return ssize_t(n);
    }
    while (true) {
      ERR_clear_error();
      const int r = SSL_read(ssl_, ptr, clamp_int(size));
      if (r > 0) return r;
      const int e = SSL_get_error(ssl_, r);
      if (e == SSL_ERROR_ZERO_RETURN) return 0;
      if (!wait(e)) return -1;
    }
  }
  bool more_ready() const override { return !ahead_.empty() || SSL_pending(ssl_) > 0; }

 private:
  // The socket is non-blocking: wait for what OpenSSL asks for, up to the timeouts.
  bool wait(int ssl_error) const {
    if (ssl_error == SSL_ERROR_WANT_READ) return wait_for_socket(fd_, POLLIN, read_s_);
    if (ssl_error == SSL_ERROR_WANT_WRITE) return wait_for_socket(fd_, POLLOUT, write_s_);
    return false;
  }
  SSL* ssl_;
  std::string& ahead_;
};

}  // namespace

TlsConnection::TlsConnection(int fd, SSL* ssl) : GateConnection(fd), ssl_(ssl) {
  SSL_set_mode(ssl_, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
}

TlsConnection::~TlsConnection() {
  SSL_free(ssl_);
}

GateConnection::Head TlsConnection::read_head(std::string& head, size_t max_head, size_t max_body) {
  if (!handshaken_) {
    ERR_clear_error();
    const int r = SSL_accept(ssl_);
    if (r <= 0) {
      const int e = SSL_get_error(ssl_, r);
      if (e == SSL_ERROR_WANT_READ) return Head::kWaitRead;
      if (e == SSL_ERROR_WANT_WRITE) return Head::kWaitWrite;
      return Head::kGone;  // a failed handshake: a wrong CA, plain HTTP, noise
    }
    handshaken_ = true;
  }
  max_head_ = max_head;
  max_body_ = max_body;
  char buf[16 * 1024];
  while (true) {
    const RequestEnd end = request_end(ahead_, max_head, max_body);
    if (end.complete) {
      head = ahead_.substr(0, end.bytes);
      ahead_.erase(0, end.bytes);
      return Head::kArrived;
    }
    if (end.too_large) return Head::kTooLarge;
    ERR_clear_error();
    const int r = SSL_read(ssl_, buf, sizeof buf);
    if (r > 0) {
      ahead_.append(buf, size_t(r));
      continue;
    }
    const int e = SSL_get_error(ssl_, r);
    if (e == SSL_ERROR_WANT_READ) return Head::kWaitRead;
    if (e == SSL_ERROR_WANT_WRITE) return Head::kWaitWrite;
    return Head::kGone;
  }
}

bool TlsConnection::has_read_ahead() const {
  // Only what lets read_head go further: part of a request waits for the socket like any
  // other.
  return SSL_pending(ssl_) > 0 || request_end(ahead_, max_head_, max_body_).complete;
}

void TlsConnection::refuse(const std::string& answer) {
  if (!handshaken_) return;  // nothing can be said to a client without a session
  ERR_clear_error();
  if (SSL_write(ssl_, answer.data(), clamp_int(answer.size())) > 0) SSL_shutdown(ssl_);
}

std::unique_ptr<httplib::Stream> TlsConnection::stream(std::string& head, time_t read_s,
                                                       time_t write_s) {
  return std::make_unique<TlsStream>(fd_, ssl_, ahead_, head, read_s, write_s);
}

}  // namespace rangex
