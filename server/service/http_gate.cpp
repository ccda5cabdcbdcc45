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
#include "service/steady_ns.h"

namespace rangex {

namespace {
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

GateConnection::~GateConnection() {
  ::shutdown(fd_, SHUT_RDWR);
  ::close(fd_);
}

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
  ready_.clear();
}

void HttpGate::admit(std::unique_ptr<GateConnection> c) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stop_) return;  // closed as it goes
    const std::string client = peer_address(c->fd());
    incoming_.push_back({std::move(c), steady_ns(), client, POLLIN});
  }
  const char b = 0;
  [[maybe_unused]] ssize_t n = ::write(wake_[1], &b, 1);
}

void HttpGate::poll_loop() {
  std::vector<Waiting> waiting;
  std::vector<pollfd> fds;
  const int64_t timeout_ns = int64_t(opt_.head_timeout_s * 1e9);
  const std::string timed_out =
      "HTTP/1.1 408 Request Timeout\r\nConnection: close\r\nContent-Length: 0\r\n\r\n";
  const std::string busy =
      "HTTP/1.1 503 Service Unavailable\r\nConnection: close\r\nContent-Length: 0\r\n\r\n";
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
        if (oldest != waiting.end()) waiting.erase(oldest);  // closes it
        waiting.push_back(std::move(w));
      }
      incoming_.clear();
    }
    fds.assign(1, pollfd{wake_[0], POLLIN, 0});
    bool read_ahead = false;
    for (const Waiting& w : waiting) {
      fds.push_back({w.conn->fd(), w.events, 0});
      read_ahead = read_ahead || w.conn->has_read_ahead();
    }
    // A kept-alive TLS connection may hold its next request already decrypted: no wait then.
    ::poll(fds.data(), fds.size(), read_ahead ? 0 : 200);
    if (fds[0].revents) {
      char sink[256];
      while (::read(wake_[0], sink, sizeof sink) > 0) {
      }
    }
    const int64_t now = steady_ns();
    std::vector<Waiting> still;
    std::vector<Ready> heads;
    for (size_t k = 0; k < waiting.size(); ++k) {
      Waiting& w = waiting[k];
      if (fds[k + 1].revents || w.conn->has_read_ahead()) {
        std::string head;
        switch (w.conn->read_head(head, opt_.max_head_bytes, opt_.max_body_bytes)) {
          case GateConnection::Head::kArrived:
            heads.emplace_back(std::move(w.conn), std::move(head));
            continue;
          case GateConnection::Head::kGone:
            continue;  // closed as it goes
          case GateConnection::Head::kTooLarge:
            w.conn->refuse(too_large_answer_);
            continue;
          case GateConnection::Head::kWaitRead:
            w.events = POLLIN;
            break;
          case GateConnection::Head::kWaitWrite:
            w.events = POLLOUT;
            break;
        }
      }
      if (now - w.since_ns > timeout_ns) {
        w.conn->refuse(timed_out);
        continue;
      }
      still.push_back(std::move(w));
    }
    waiting.swap(still);
    std::lock_guard<std::mutex> lock(mu_);
    for (Ready& h : heads) {
      // Every worker busy and as many requests waiting for one as may wait for their
      // heads: this one is answered busy rather than queued without end.
      if (ready_.size() >= opt_.max_waiting) {
        h.first->refuse(busy);
        continue;
      }
      ready_.push_back(std::move(h));
    }
    if (!heads.empty()) ready_cv_.notify_all();
  }
  waiting.clear();
  std::lock_guard<std::mutex> lock(mu_);
  incoming_.clear();
}

void HttpGate::worker() {
  while (true) {
    Ready job;
    {
      std::unique_lock<std::mutex> lock(mu_);
      ready_cv_.wait(lock, [&] { return stop_ || !ready_.empty(); });
      if (stop_) return;
      job = std::move(ready_.front());
      ready_.pop_front();
    }
    bool keep = false;
    try {
      keep = serve_(*job.first, job.second);
    } catch (...) {
      keep = false;
    }
    if (keep) admit(std::move(job.first));
  }
}

}  // namespace rangex
