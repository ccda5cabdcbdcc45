// The fleet view's image relay (fleet/image_relay.h) against dashboards that do not behave: one
// that sends its answer a byte at a time, its head or its body, and one that sends more than
// any fillet's image. Each relay ends by its deadline or its bound, naming the server, and
// the fleet's worker is free again.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <future>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "fleet/image_relay.h"

using namespace rangex;

namespace {

// A dashboard on loopback that reads each request's head and answers with `answer(fd)`, until
// it is destroyed (then every connection it holds is closed, so a relay still reading ends).
class FakeDashboard {
 public:
  explicit FakeDashboard(std::function<void(int fd, const std::atomic<bool>& stop)> answer)
      : answer_(std::move(answer)) {
    listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(listener_, reinterpret_cast<sockaddr*>(&a), sizeof a);
    ::listen(listener_, 4);
    socklen_t n = sizeof a;
    ::getsockname(listener_, reinterpret_cast<sockaddr*>(&a), &n);
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { serve(); });
  }
  ~FakeDashboard() {
    stop();
    thread_.join();
    ::close(listener_);
  }
  void stop() { stop_ = true; }  // ends the answer being sent, and closes its connection
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }

 private:
  void serve() {
    while (!stop_) {
      pollfd p{listener_, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const int fd = ::accept(listener_, nullptr, nullptr);
      if (fd < 0) continue;
      std::string head;
      char c;
      while (!stop_ && head.find("\r\n\r\n") == std::string::npos && ::recv(fd, &c, 1, 0) == 1)
        head += c;
      answer_(fd, stop_);
      ::close(fd);
    }
  }
  std::function<void(int, const std::atomic<bool>&)> answer_;
  int listener_ = -1, port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

void send_all(int fd, const std::string& s) {
  size_t sent = 0;
  while (sent < s.size()) {
    const ssize_t n = ::send(fd, s.data() + sent, s.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return;
    sent += size_t(n);
  }
}

// `text` a byte every 100 ms (each within the relay's 1 s read timeout), until stopped.
void trickle(int fd, const std::string& text, const std::atomic<bool>& stop) {
  for (size_t i = 0; !stop; i = (i + 1) % text.size()) {
    if (::send(fd, &text[i], 1, MSG_NOSIGNAL) != 1) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

ImageRelayRequest request(const FakeDashboard& d) {
  ImageRelayRequest r;
  r.server = "srv-b";
  r.url = d.url();
  r.path = "/api/fillets/7/images/xray";
  r.timeout_s = 1;
  return r;
}

// The relay from `d`, given 60 s to end (a hang bound; it must end about its deadline). Past
// it, the dashboard stops sending, so that the relay ends and the test fails instead of hanging.
RelayedImage relay_within_bound(FakeDashboard& d, const ImageRelayRequest& r) {
  auto done = std::async(std::launch::async, [r] { return relay_image(r); });
  if (done.wait_for(std::chrono::seconds(60)) != std::future_status::ready) {
    ADD_FAILURE() << "the relay was still reading after 60 s";
    d.stop();
  }
  return done.get();
}

std::string error_of(const RelayedImage& got) {
  const nlohmann::json j = nlohmann::json::parse(got.body, nullptr, false);
  EXPECT_TRUE(j.is_object()) << got.body;
  if (!j.is_object()) return "";
  EXPECT_EQ(j.value("server", ""), "srv-b");
  return j.value("error", "");
}

}  // namespace

// An answer whose head or body comes a byte at a time, each byte well within the read timeout.
TEST(ImageRelay, AnAnswerSentAByteAtATimeIsCutAtTheDeadline) {
  const std::pair<std::string, std::string> answers[] = {
      {"HTTP/1.1 200 OK\r\nContent-Type: image/png\r\nContent-Length: 1000000\r\n\r\n",
       "\x89PNG"},                                  // the body
      {"HTTP/1.1 200 OK\r\n", "X-Slow: yes\r\n"}};  // the head
  for (const auto& [at_once, trickled] : answers) {
    RelayedImage got;
    {
      FakeDashboard d([&](int fd, const std::atomic<bool>& stop) {
        send_all(fd, at_once);
        trickle(fd, trickled, stop);
      });
      got = relay_within_bound(d, request(d));
    }
    EXPECT_EQ(got.status, 502) << at_once;
    const std::string why = error_of(got);
    EXPECT_NE(why.find("server srv-b at http://127.0.0.1:"), std::string::npos) << why;
    EXPECT_NE(why.find("did not send the image within 1 s"), std::string::npos) << why;
  }
}

TEST(ImageRelay, MoreThanAnyFilletsImageIsRefused) {
  RelayedImage got;
  {
    FakeDashboard d([](int fd, const std::atomic<bool>&) {
      const size_t size = size_t(100) << 20;
      send_all(fd, "HTTP/1.1 200 OK\r\nContent-Type: image/png\r\nContent-Length: " +
                       std::to_string(size) + "\r\n\r\n");
      const std::string block(size_t(1) << 20, '\0');
      for (size_t sent = 0; sent < size; sent += block.size()) send_all(fd, block);
    });
    ImageRelayRequest r = request(d);
    r.timeout_s = 30;  // the bound, not the deadline, ends it
    got = relay_within_bound(d, r);
  }
  EXPECT_EQ(got.status, 502);
  EXPECT_NE(error_of(got).find("more than 64 MiB for one image"), std::string::npos) << got.body;
}

// A dashboard that behaves is relayed as it answered, a refusal too.
TEST(ImageRelay, AnAnswerWithinTheDeadlineIsRelayedAsItCame) {
  const std::string png("\x89PNG\r\n\x1a\n\0\1\2", 11);
  RelayedImage got;
  {
    FakeDashboard d([&](int fd, const std::atomic<bool>&) {
      send_all(fd, "HTTP/1.1 200 OK\r\nContent-Type: image/png\r\nContent-Length: " +
                       std::to_string(png.size()) + "\r\nConnection: close\r\n\r\n" + png);
    });
    got = relay_within_bound(d, request(d));
  }
  EXPECT_EQ(got.status, 200);
  EXPECT_EQ(got.type, "image/png");
  EXPECT_EQ(got.body, png);
  {
    FakeDashboard d([](int fd, const std::atomic<bool>&) {
      const std::string body = R"({"error": "fillet 7 has no xray image"})";
      send_all(fd, "HTTP/1.1 404 Not Found\r\nContent-Type: application/json\r\nContent-Length: " +
                       std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body);
    });
    got = relay_within_bound(d, request(d));
  }
  EXPECT_EQ(got.status, 404);
  EXPECT_NE(got.body.find("has no xray image"), std::string::npos) << got.body;
}
