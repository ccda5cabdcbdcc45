#include "service/gated_http_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <cctype>
#include <cstring>

namespace rangex {

namespace {

thread_local int t_fd = -1;

bool wait_for(int fd, short events, time_t sec, time_t usec) {
  pollfd p{fd, events, 0};
  const int ms = int(sec * 1000 + usec / 1000);
  int r;
  do r = ::poll(&p, 1, ms);
  while (r < 0 && errno == EINTR);
  return r > 0 && (p.revents & (events | POLLHUP | POLLERR));
}

void address_of(const sockaddr_storage& a, std::string& ip, int& port) {
  char buf[INET6_ADDRSTRLEN] = "";
  if (a.ss_family == AF_INET) {
    const auto* v4 = reinterpret_cast<const sockaddr_in*>(&a);
    inet_ntop(AF_INET, &v4->sin_addr, buf, sizeof buf);
    port = ntohs(v4->sin_port);
  } else if (a.ss_family == AF_INET6) {
    const auto* v6 = reinterpret_cast<const sockaddr_in6*>(&a);
    inet_ntop(AF_INET6, &v6->sin6_addr, buf, sizeof buf);
    port = ntohs(v6->sin6_port);
  }
  ip = buf;
}

// The request head the gate read, then the socket (bodies; never beyond what is asked, so
// the next request on the connection stays in the socket for the gate).
class GateStream : public httplib::Stream {
 public:
  GateStream(int fd, std::string& head, time_t read_s, time_t write_s)
      : fd_(fd), head_(head), read_s_(read_s), write_s_(write_s) {}
  bool is_readable() const override {
    return at_ < head_.size() || wait_for(fd_, POLLIN, read_s_, 0);
  }
  bool is_writable() const override { return wait_for(fd_, POLLOUT, write_s_, 0); }
  ssize_t read(char* ptr, size_t size) override {
    if (at_ < head_.size()) {
      const size_t n = std::min(size, head_.size() - at_);
      std::memcpy(ptr, head_.data() + at_, n);
      at_ += n;
      return ssize_t(n);
    }
    if (!wait_for(fd_, POLLIN, read_s_, 0)) return -1;
    return ::recv(fd_, ptr, size, 0);
  }
  ssize_t write(const char* ptr, size_t size) override {
    if (!is_writable()) return -1;
    return ::send(fd_, ptr, size, MSG_NOSIGNAL);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage a{};
    socklen_t n = sizeof a;
    if (::getpeername(fd_, reinterpret_cast<sockaddr*>(&a), &n) == 0) address_of(a, ip, port);
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage a{};
    socklen_t n = sizeof a;
    if (::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &n) == 0) address_of(a, ip, port);
  }
  socket_t socket() const override { return fd_; }

 private:
  int fd_;
  std::string& head_;
  size_t at_ = 0;
  time_t read_s_, write_s_;
};

// Our API takes no request bodies: one announced is refused before a worker would wait for
// it (a slow body is the slow head's twin).
bool announces_body(const std::string& head) {
  std::string lower(head);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  if (lower.find("\r\ntransfer-encoding:") != std::string::npos) return true;
  const size_t at = lower.find("\r\ncontent-length:");
  if (at == std::string::npos) return false;
  size_t k = at + 17;
  while (k < lower.size() && (lower[k] == ' ' || lower[k] == '\t')) ++k;
  while (k < lower.size() && lower[k] == '0') ++k;
  return k < lower.size() && std::isdigit(static_cast<unsigned char>(lower[k]));
}

}  // namespace

GatedHttpServer::GatedHttpServer(GateOptions opt)
    : gate_(std::make_unique<HttpGate>(
          opt, [this](int fd, std::string& head) { return serve(fd, head); })) {
  // Accepting is all that httplib's own pool still does: a few threads are plenty.
  new_task_queue = [] { return new httplib::ThreadPool(2); };
}

GatedHttpServer::~GatedHttpServer() {
  gate_->stop();
}

int GatedHttpServer::current_fd() {
  return t_fd;
}

bool GatedHttpServer::process_and_close_socket(socket_t sock) {
  gate_->admit(sock);
  return true;
}

bool GatedHttpServer::serve(int fd, std::string& head) {
  if (announces_body(head)) {
    static const char kRefuse[] =
        "HTTP/1.1 413 Payload Too Large\r\nConnection: close\r\nContent-Type: "
        "application/json\r\nContent-Length: 42\r\n\r\n{\"error\":\"this API takes no request "
        "body\"}";
    [[maybe_unused]] ssize_t n = ::send(fd, kRefuse, sizeof kRefuse - 1, MSG_NOSIGNAL);
    return false;
  }
  GateStream strm(fd, head, read_timeout_sec_, write_timeout_sec_);
  bool closed = false;
  t_fd = fd;
  const bool ok = process_request(strm, false, closed, nullptr);
  t_fd = -1;
  return ok && !closed && is_running();
}

}  // namespace rangex
