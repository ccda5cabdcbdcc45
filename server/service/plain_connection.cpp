#include "service/plain_connection.h"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>

#include "service/gate_stream.h"
#include "service/request_end.h"

namespace rangex {

namespace {
class PlainStream : public GateStream {
 public:
  using GateStream::GateStream;
  ssize_t write(const char* ptr, size_t size) override {
    if (!is_writable()) return -1;
    return ::send(fd_, ptr, size, MSG_NOSIGNAL);
  }

 protected:
  ssize_t read_more(char* ptr, size_t size) override {
    if (!wait_for_socket(fd_, POLLIN, read_s_)) return -1;
    return ::recv(fd_, ptr, size, 0);
  }
};
}  // namespace

GateConnection::Head PlainConnection::read_head(std::string& head, size_t max_head,
                                                size_t max_body) {
  // One buffer for the gate's thread, not one a connection: hundreds may be waiting.
  thread_local std::string peek;
  peek.resize(max_head + 4 + max_body + 1);
  const ssize_t n = ::recv(fd_, peek.data(), peek.size(), MSG_PEEK | MSG_DONTWAIT);
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return Head::kWaitRead;
  if (n <= 0) return Head::kGone;
  const RequestEnd e = request_end(std::string_view(peek.data(), size_t(n)), max_head, max_body);
  if (e.too_large) return Head::kTooLarge;
  if (!e.complete) return Head::kWaitRead;
  // Exactly the request: the next one stays in the socket.
  head.resize(e.bytes);
  if (::recv(fd_, head.data(), head.size(), MSG_DONTWAIT) != ssize_t(head.size()))
    return Head::kGone;
  return Head::kArrived;
}

void PlainConnection::refuse(const std::string& answer) {
  [[maybe_unused]] ssize_t n =
      ::send(fd_, answer.data(), answer.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

std::unique_ptr<httplib::Stream> PlainConnection::stream(std::string& head, time_t read_s,
                                                         time_t write_s) {
  return std::make_unique<PlainStream>(fd_, head, read_s, write_s);
}

}  // namespace rangex
