#include "service/http_gate.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

#include "core/error.h"

namespace rangex {

namespace {
int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
std::string peer_address(int fd) {
  sockaddr_storage a{};
  socklen_t n = sizeof a;
  char buf[INET6_ADDRSTRLEN] = "";
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&a), &n) != 0) return "";
  if (a.ss_family == AF_INET)
    inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(&a)->sin_addr, buf, sizeof buf);
  else if (a.ss_family == AF_INET6)
    inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6*>(&a)->sin6_addr, buf, sizeof buf);
  return buf;
}
}  // namespace

HttpGate::HttpGate(GateOptions opt, Serve serve) : opt_(opt), serve_(std::move(serve)) {
  const std::string body =
      "{\"error\":\"request head larger than " + std::to_string(opt_.max_head_bytes) + " bytes\"}";
  too_large_answer_ =
      "HTTP/1.1 431 Request Header Fields Too Large\r\nConnection: close\r\n"
      "Content-Type: application/json\r\nContent-Length: " +
      std::to_string(body.size()) + "\r\n\r\n" + body;
  if (pipe2(wake_, O_CLOEXEC | O_NONBLOCK) != 0)
    fail("http: cannot make the gate's wake pipe (", std::strerror(errno), ")");
  poller_ = std::thread([this] { poll_loop(); });
  for (int k = 0; k < opt_.workers; ++k) workers_.emplace_back([this] { worker(); });
}

HttpGate::~HttpGate() {
  stop();
  ::close(wake_[0]);
  ::close(wake_[1]);
}

void HttpGate::stop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stop_) return;
    stop_ = true;
  }
  const char b = 0;
  [[maybe_unused]] ssize_t n = ::write(wake_[1], &b, 1);
  ready_cv_.notify_all();
  if (poller_.joinable()) poller_.join();
  for (std::thread& t : workers_)
    if (t.joinable()) t.join();
  for (auto& [fd, head] : ready_) ::close(fd);
  ready_.clear();
}

void HttpGate::admit(int fd) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stop_) {
      ::close(fd);
      return;
    }
    incoming_.push_back({fd, steady_ns(), peer_address(fd)});
  }
  const char b = 0;
  [[maybe_unused]] ssize_t n = ::write(wake_[1], &b, 1);
}

void HttpGate::close_now(int fd, const char* answer) {
  if (answer) {
    [[maybe_unused]] ssize_t n =
        ::send(fd, answer, std::strlen(answer), MSG_NOSIGNAL | MSG_DONTWAIT);
  }
  ::shutdown(fd, SHUT_RDWR);
  ::close(fd);
}

void HttpGate::poll_loop() {
  std::vector<Waiting> waiting;
  std::vector<pollfd> fds;
  std::string peek(opt_.max_head_bytes + 1, '\0');
  const int64_t timeout_ns = int64_t(opt_.head_timeout_s * 1e9);
  while (true) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (stop_) break;
      for (Waiting& w : incoming_) {
        // Full: the connection that has waited longest gives way; first among those of
        // the newcomer's address when that address is over its own bound.
        const size_t same =
            size_t(std::count_if(waiting.begin(), waiting.end(),
                                 [&](const Waiting& o) { return o.client == w.client; }));
        auto oldest = waiting.end();
        if (same >= opt_.max_waiting_per_client)
          oldest = std::find_if(waiting.begin(), waiting.end(),
                                [&](const Waiting& o) { return o.client == w.client; });
        else if (waiting.size() >= opt_.max_waiting)
          oldest = waiting.begin();
        if (oldest != waiting.end()) {
          close_now(oldest->fd, nullptr);
          waiting.erase(oldest);
        }
        waiting.push_back(std::move(w));
      }
      incoming_.clear();
    }
    fds.assign(1, pollfd{wake_[0], POLLIN, 0});
    for (const Waiting& w : waiting) fds.push_back({w.fd, POLLIN, 0});
    ::poll(fds.data(), fds.size(), 200);
    if (fds[0].revents) {
      char sink[256];
      while (::read(wake_[0], sink, sizeof sink) > 0) {
      }
    }
    const int64_t now = steady_ns();
    std::vector<Waiting> still;
    std::vector<std::pair<int, std::string>> heads;
    for (size_t k = 0; k < waiting.size(); ++k) {
      const Waiting& w = waiting[k];
      if (fds[k + 1].revents) {
        const ssize_t n = ::recv(w.fd, peek.data(), peek.size(), MSG_PEEK | MSG_DONTWAIT);
        if (n <= 0 && !(n < 0 && (errno == EAGAIN || errno == EINTR))) {
          ::close(w.fd);  // gone
          continue;
        }
        if (n > 0) {
          const std::string_view got(peek.data(), size_t(n));
          const size_t end = got.find("\r\n\r\n");
          if (end != std::string_view::npos) {
            std::string head(end + 4, '\0');
            // Exactly the head: the body (if any) and the next request stay in the socket.
            if (::recv(w.fd, head.data(), head.size(), MSG_DONTWAIT) == ssize_t(head.size())) {
              heads.emplace_back(w.fd, std::move(head));
            } else {
              ::close(w.fd);
            }
            continue;
          }
          if (size_t(n) > opt_.max_head_bytes) {
            close_now(w.fd, too_large_answer_.c_str());
            continue;
          }
        }
      }
      if (now - w.since_ns > timeout_ns) {
        close_now(w.fd,
                  "HTTP/1.1 408 Request Timeout\r\nConnection: close\r\n"
                  "Content-Length: 0\r\n\r\n");
        continue;
      }
      still.push_back(w);
    }
    waiting.swap(still);
    std::lock_guard<std::mutex> lock(mu_);
    for (auto& h : heads) {
      // Every worker busy and as many requests waiting for one as may wait for their
      // heads: this one is answered busy rather than queued without end.
      if (ready_.size() >= opt_.max_waiting) {
        close_now(h.first,
                  "HTTP/1.1 503 Service Unavailable\r\nConnection: close\r\n"
                  "Content-Length: 0\r\n\r\n");
        continue;
      }
      ready_.push_back(std::move(h));
    }
    if (!heads.empty()) ready_cv_.notify_all();
  }
  for (const Waiting& w : waiting) ::close(w.fd);
  std::lock_guard<std::mutex> lock(mu_);
  for (const Waiting& w : incoming_) ::close(w.fd);
  incoming_.clear();
}

void HttpGate::worker() {
  while (true) {
    std::pair<int, std::string> job;
    {
      std::unique_lock<std::mutex> lock(mu_);
      ready_cv_.wait(lock, [&] { return stop_ || !ready_.empty(); });
      if (stop_) return;
      job = std::move(ready_.front());
      ready_.pop_front();
    }
    bool keep = false;
    try {
      keep = serve_(job.first, job.second);
    } catch (...) {
      keep = false;
    }
    if (keep)
      admit(job.first);
    else
      close_now(job.first, nullptr);
  }
}

}  // namespace rangex
