// One connection at the HTTP gate, plain or TLS. The gate's one thread only ever asks it to
// read toward a request head without blocking; a worker then serves that request through
// the connection's stream, which reads the head first.
#pragma once
#include <cstddef>
#include <ctime>
#include <memory>
#include <string>

namespace httplib {
class Stream;
}  // namespace httplib
struct ssl_st;

namespace rangex {

class GateConnection {
 public:
  enum class Head { kWaitRead, kWaitWrite, kArrived, kGone, kTooLarge };
  explicit GateConnection(int fd) : fd_(fd) {}
  virtual ~GateConnection();  // shuts the socket down and closes it
  GateConnection(const GateConnection&) = delete;
  GateConnection& operator=(const GateConnection&) = delete;

  int fd() const { return fd_; }
  // Reads toward the next request, never blocking; kArrived puts its head (ending in its
  // empty line) and its body, when that is at most max_body bytes, in head
  // (service/request_end.h). kWaitRead/kWaitWrite: call again once the socket is ready so.
  virtual Head read_head(std::string& head, size_t max_head, size_t max_body) = 0;
  // Bytes of the next request already taken off the socket (TLS decrypts whole records):
  // poll() will not announce them, so the gate reads again without waiting.
  virtual bool has_read_ahead() const { return false; }
  // A short answer before closing, best effort and never blocking.
  virtual void refuse(const std::string& answer) = 0;
  // The stream a worker serves one request through: head first, then the connection.
  virtual std::unique_ptr<httplib::Stream> stream(std::string& head, time_t read_s,
                                                  time_t write_s) = 0;
  virtual ssl_st* tls() const { return nullptr; }

 protected:
  int fd_;
};

}  // namespace rangex
