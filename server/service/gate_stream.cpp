#include "service/gate_stream.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace rangex {

namespace {
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
}  // namespace

bool wait_for_socket(int fd, short events, time_t sec) {
  pollfd p{fd, events, 0};
  int r;
  do r = ::poll(&p, 1, int(sec * 1000));
  while (r < 0 && errno == EINTR);
  return r > 0 && (p.revents & (events | POLLHUP | POLLERR));
}

bool GateStream::is_readable() const {
  return at_ < head_.size() || more_ready() || wait_for_socket(fd_, POLLIN, read_s_);
}

bool GateStream::is_writable() const {
  return wait_for_socket(fd_, POLLOUT, write_s_);
}

ssize_t GateStream::read(char* ptr, size_t size) {
  if (at_ < head_.size()) {
    const size_t n = std::min(size, head_.size() - at_);
    std::memcpy(ptr, head_.data() + at_, n);
    at_ += n;
    return ssize_t(n);
  }
  return read_more(ptr, size);
}

void GateStream::get_remote_ip_and_port(std::string& ip, int& port) const {
  sockaddr_storage a{};
  socklen_t n = sizeof a;
  if (::getpeername(fd_, reinterpret_cast<sockaddr*>(&a), &n) == 0) address_of(a, ip, port);
}

void GateStream::get_local_ip_and_port(std::string& ip, int& port) const {
  sockaddr_storage a{};
  socklen_t n = sizeof a;
  if (::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &n) == 0) address_of(a, ip, port);
}

}  // namespace rangex
