// The HTTP side against requests a plant's network can hold: multi-range bombs and
// header floods are refused small and fast, and the dashboard's API answers throughout.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <openssl/ssl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/plant_config.h"
#include "csv_export.h"
#include "service/http_server.h"
#include "service/server.h"
#include "temp_dir.h"
#include "test_ca.h"

using namespace rangex;

namespace {

ServerOptions options(const test::TempDir& t) {
  ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.data_dir = t.str("data");
  o.engine.backend.name = "cpu";
  return o;
}

HttpOptions http_options(bool tls = false) {
  HttpOptions ho;
  ho.listen = "127.0.0.1:0";
  if (tls) {
    ho.security.tls_cert = test::test_ca("server.crt");
    ho.security.tls_key = test::test_ca("server.key");
  }
  return ho;
}

// A one-lane rangexd with its HTTP side and a client of it.
struct Plant {
  test::TempDir dir;
  RangexServer server{default_plant_config(1), options(dir)};
  HttpServer web{server.engine(), server.store(), server.hub(), http_options()};
  httplib::Client client{"127.0.0.1", web.port()};
  Plant() { client.set_read_timeout(10, 0); }
};

// A raw connection to the HTTP side (-1 when it cannot be had).
int connect_to(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// One slowloris connection: a request head a byte at a time; over TLS either the head in a
// session (a record a byte) or, before any session, the handshake itself; or a whole head
// at once and then its small body a byte at a time.
struct SlowClient {
  enum Kind { kHead, kTlsHead, kTlsHandshake, kBody } kind;
  int fd = -1;
  SSL* ssl = nullptr;
  size_t sent = 0;
  void close() {
    if (ssl) SSL_free(ssl);
    if (fd >= 0) ::close(fd);
    ssl = nullptr;
    fd = -1;
  }
  // Connects when not connected; false when that fails (tried again next round).
  bool connect(int port, SSL_CTX* ctx) {
    if (fd >= 0) return true;
    sent = 0;
    fd = connect_to(port);
    if (fd < 0) return false;
    timeval tv{5, 0};  // a hang bound for the handshake below
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    if (kind != kTlsHead) return true;
    ssl = SSL_new(ctx);
    SSL_set_fd(ssl, fd);
    if (SSL_connect(ssl) != 1) close();
    return fd >= 0;
  }
  bool send_one() {
    static const std::string head = "GET /api/statistics HTTP/1.1\r\nHost: rangex\r\nX-Slow: ";
    // A TLS record header announcing 512 bytes of handshake, then its bytes one by one.
    static const std::string hello = std::string("\x16\x03\x01\x02\x00", 5);
    static const std::string post =
        "POST /api/lanes/0/verification HTTP/1.1\r\nHost: rangex\r\nContent-Type: "
        "application/json\r\nContent-Length: 1000\r\n\r\n";
    if (kind == kBody && sent == 0) {
      sent = post.size();
      return ::send(fd, post.data(), post.size(), MSG_NOSIGNAL) == ssize_t(post.size());
    }
    const std::string& text = kind == kTlsHandshake ? hello : head;
    const char b = sent < text.size() && kind != kBody ? text[sent] : 'x';
    ++sent;
    if (ssl) return SSL_write(ssl, &b, 1) == 1;
    return ::send(fd, &b, 1, MSG_NOSIGNAL) == 1;
  }
};

// Asks the API for its statistics over a new connection: the seconds it took, or -1.
double timed_statistics(int port, bool tls, int answered) {
  std::unique_ptr<httplib::ClientImpl> c;
  if (tls) {
    auto ssl = std::make_unique<httplib::SSLClient>("127.0.0.1", port);
    ssl->enable_server_certificate_verification(false);
    c = std::move(ssl);
  } else {
    c = std::make_unique<httplib::ClientImpl>("127.0.0.1", port);
  }
  c->set_connection_timeout(10, 0);
  c->set_read_timeout(10, 0);  // a hang bound; the slowest answer is reported
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = c->Get("/api/statistics");
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_TRUE(r) << "request " << answered << (tls ? " over TLS" : "") << ": "
                 << httplib::to_string(r.error());
  if (!r) return -1;
  EXPECT_EQ(r->status, 200);
  return s;
}

// Slowloris: connections that send a request head (or a TLS handshake) a byte every 3 s,
// reconnecting when the server closes them, while the API is asked for its statistics every
// 200 ms; returns the slowest answer in seconds (a failed request is a failure of the test).
double api_under_slow_clients(int clients, double seconds, bool tls = false, bool bodies = false) {
  test::TempDir dir;
  RangexServer server{default_plant_config(1), options(dir)};
  HttpServer web{server.engine(), server.store(), server.hub(), http_options(tls)};
  const int port = web.port();
  std::atomic<bool> done{false};
  std::thread slow([&] {
    SSL_CTX* ctx = SSL_CTX_new(TLS_client_method());
    std::vector<SlowClient> conns(static_cast<size_t>(clients));
    for (int k = 0; k < clients; ++k)
      conns[size_t(k)].kind = bodies  ? SlowClient::kBody
                              : !tls  ? SlowClient::kHead
                              : k % 2 ? SlowClient::kTlsHead
                                      : SlowClient::kTlsHandshake;
    while (!done) {
      for (SlowClient& c : conns) {
        if (done) break;
        if (c.connect(port, ctx) && !c.send_one()) c.close();
      }
      for (int t = 0; t < 30 && !done; ++t)
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    for (SlowClient& c : conns) c.close();
    SSL_CTX_free(ctx);
  });
  // The slow clients first: every one of them connected and waiting.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  double slowest = 0;
  int answered = 0;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    const double s = timed_statistics(port, tls, answered);
    if (s < 0) break;
    slowest = std::max(slowest, s);
    ++answered;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  done = true;
  slow.join();
  EXPECT_GT(answered, 10);
  std::printf("%d slow clients%s: %d answers, the slowest in %.3f s\n", clients,
              tls ? " over TLS" : "", answered, slowest);
  return slowest;
}

}  // namespace

TEST(HttpHostile, FortyAndThreeHundredSlowClientsLeaveTheApiAnswering) {
  // 40 once held every thread of httplib's pool; 300 are more than the threads there are.
  // Each head needs 45 s at a byte every 3 s: longer than the gate waits for one (10 s), so
  // every slow client is also closed and comes back.
  for (const int clients : {40, 300}) {
    const double slowest = api_under_slow_clients(clients, 15);
    // A hang bound, not a speed test: the figure above is what the closing note reports.
    EXPECT_LT(slowest, 10.0) << clients << " slow clients";
  }
}

TEST(HttpHostile, SlowTlsHandshakesAndHeadsLeaveTheApiAnswering) {
  // Half the clients send their handshake a byte every 3 s, half their request head inside
  // a session: neither holds a worker (the gate steps handshakes without blocking).
  const double slowest = api_under_slow_clients(300, 15, true);
  EXPECT_LT(slowest, 10.0);  // a hang bound, not a speed test
}

TEST(HttpHostile, SlowBodiesLeaveTheApiAnsweringAndAWholeOneIsServed) {
  // Sixty clients send a whole head announcing a 1,000-byte body, then a byte every 3 s: the
  // gate waits for a body as for a head, so none holds a worker.
  const double slowest = api_under_slow_clients(60, 10, false, true);
  EXPECT_LT(slowest, 10.0);  // a hang bound, not a speed test
  Plant plant;
  const auto r =
      plant.client.Post("/api/lanes/0/verification",
                        R"({"piece": "2 mm calcified sphere", "x_mm": 10})", "application/json");
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  EXPECT_EQ(r->status, 200) << r->body;
  EXPECT_TRUE(plant.server.engine().lane_state(0).verification.running);
  // A body over the gate's bound is refused unread.
  const auto big =
      plant.client.Post("/api/lanes/0/verification", std::string(20000, ' '), "application/json");
  ASSERT_TRUE(big);
  EXPECT_EQ(big->status, 413);
  EXPECT_NE(big->body.find("at most 16384 bytes"), std::string::npos) << big->body;
}

TEST(HttpHostile, TlsKeepsItsConnectionAliveAcrossRequests) {
  test::TempDir dir;
  RangexServer server{default_plant_config(1), options(dir)};
  HttpServer web{server.engine(), server.store(), server.hub(), http_options(true)};
  httplib::SSLClient c("127.0.0.1", web.port());
  c.enable_server_certificate_verification(false);
  c.set_keep_alive(true);
  c.set_read_timeout(10, 0);
  for (int k = 0; k < 5; ++k) {
    const auto r = c.Get(k % 2 ? "/api/info" : "/api/statistics");
    ASSERT_TRUE(r) << "request " << k << ": " << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 200);
    EXPECT_FALSE(r->body.empty());
  }
  // A plain-HTTP request to the TLS port is no handshake: closed, and the server goes on.
  const int fd = connect_to(web.port());
  ASSERT_GE(fd, 0);
  const std::string req = "GET /api/info HTTP/1.1\r\nHost: rangex\r\n\r\n";
  ::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
  timeval tv{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  char buf[64];
  const ssize_t n = ::recv(fd, buf, sizeof buf, 0);  // nothing, or a TLS alert
  EXPECT_TRUE(n <= 0 || std::string(buf, size_t(n)).find("HTTP/1.1") == std::string::npos);
  ::close(fd);
  const auto again = c.Get("/api/statistics");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 200);
  web.stop();
}

TEST(HttpHostile, EventClientsThatNeverReadAreDroppedAndARealOneConnects) {
  Plant plant;
  const int port = plant.web.port();
  // Fifty event clients that send their request and never read a byte: 32 streams (the
  // limit) fill with them, the rest are refused.
  std::vector<int> deaf;
  for (int k = 0; k < 50; ++k) {
    const int fd = connect_to(port);
    ASSERT_GE(fd, 0);
    const std::string req = "GET /api/events HTTP/1.1\r\nHost: rangex\r\n\r\n";
    ASSERT_EQ(::send(fd, req.data(), req.size(), MSG_NOSIGNAL), ssize_t(req.size()));
    deaf.push_back(fd);
  }
  for (int k = 0; k < 500 && plant.web.event_streams() < 32; ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(plant.web.event_streams(), 32);
  // A real dashboard asks until it gets a stream: once the deaf ones have fallen behind
  // (their buffers full of beats), one of them gives way. Bounded: 120 s.
  bool streamed = false;
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  int refused = 0;
  while (!streamed && std::chrono::steady_clock::now() < end) {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(10, 0);
    int status = 0;
    const auto r = c.Get(
        "/api/events",
        [&](const httplib::Response& res) {
          status = res.status;
          return true;
        },
        [&](const char*, size_t) {
          streamed = status == 200;
          return false;  // one chunk is enough
        });
    if (!streamed) {
      ++refused;
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
  }
  EXPECT_TRUE(streamed) << "no event stream within 120 s (" << refused << " refusals)";
  EXPECT_GT(plant.web.event_streams_dropped(), 0u);
  std::printf("a real event client connected after %d refusals; %llu deaf streams dropped\n",
              refused, (unsigned long long)plant.web.event_streams_dropped());
  // And the API answers.
  const auto st = plant.client.Get("/api/statistics");
  ASSERT_TRUE(st);
  EXPECT_EQ(st->status, 200);
  for (int fd : deaf) ::close(fd);
}

TEST(HttpHostile, AnAnnouncedBodyIsRefusedBeforeItIsWaitedFor) {
  Plant plant;
  const int fd = connect_to(plant.web.port());
  ASSERT_GE(fd, 0);
  // A body announced and never sent: a worker would wait for it.
  const std::string req =
      "POST /api/statistics HTTP/1.1\r\nHost: rangex\r\nContent-Length: 100000\r\n\r\n";
  ASSERT_EQ(::send(fd, req.data(), req.size(), MSG_NOSIGNAL), ssize_t(req.size()));
  timeval tv{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  char buf[512] = "";
  const ssize_t n = ::recv(fd, buf, sizeof buf - 1, 0);
  ::close(fd);
  ASSERT_GT(n, 0);
  EXPECT_NE(std::string(buf).find("413"), std::string::npos) << buf;
  const auto st = plant.client.Get("/api/statistics");
  ASSERT_TRUE(st);
  EXPECT_EQ(st->status, 200);
}

// httplib's own SO_REUSEPORT let a second server start on a port another one listens on and
// take some of its connections. A restart must still take its port back at once, though the
// connections it closed wait in TIME_WAIT there.
TEST(HttpHostile, APortAnotherServerListensOnIsRefusedAndARestartTakesItBack) {
  Plant plant;
  HttpOptions same = http_options();
  same.listen = "127.0.0.1:" + std::to_string(plant.web.port());
  try {
    HttpServer second(plant.server.engine(), plant.server.store(), plant.server.hub(), same);
    ADD_FAILURE() << "a second server listens on " << same.listen;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot listen on " + same.listen), std::string::npos)
        << e.what();
  }
  // The server closes this connection first, so its side of it waits in TIME_WAIT.
  const int fd = connect_to(plant.web.port());
  ASSERT_GE(fd, 0);
  const std::string head = "GET /api/info HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
  ASSERT_EQ(::send(fd, head.data(), head.size(), MSG_NOSIGNAL), ssize_t(head.size()));
  char buf[4096];
  std::string answer;
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) answer.append(buf, size_t(n));
  ::close(fd);
  EXPECT_EQ(answer.rfind("HTTP/1.1 200", 0), 0u) << answer.substr(0, 80);
  plant.web.stop();
  HttpServer again(plant.server.engine(), plant.server.store(), plant.server.hub(), same);
  httplib::Client c("127.0.0.1", again.port());
  c.set_read_timeout(10, 0);
  const auto r = c.Get("/api/info");
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  EXPECT_EQ(r->status, 200);
}

TEST(HttpHostile, AMultiRangeRequestIsRefusedSmallAndOneRangeIsServed) {
  Plant plant;
  httplib::Client& c = plant.client;
  const auto whole = c.Get("/api/info");
  ASSERT_TRUE(whole) << httplib::to_string(whole.error());
  ASSERT_EQ(whole->status, 200);
  ASSERT_GT(whole->body.size(), 20u);
  // 2,600 parts of the whole document: once a 248 MB answer to a 7.9 kB request.
  std::string bomb = "bytes=0-";
  for (int k = 1; k < 2600; ++k) bomb += ",0-";
  const auto r = c.Get("/api/info", {{"Range", bomb}});
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  EXPECT_EQ(r->status, 416);
  EXPECT_LT(r->body.size(), 200u);
  EXPECT_NE(r->body.find("2600 ranges"), std::string::npos) << r->body;
  // One range is still a range.
  const auto one = c.Get("/api/info", {{"Range", "bytes=0-9"}});
  ASSERT_TRUE(one);
  EXPECT_EQ(one->status, 206);
  EXPECT_EQ(one->body, whole->body.substr(0, 10));
  // And the server answers as before.
  const auto again = c.Get("/api/statistics");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 200);
}

// A value that is not UTF-8 (%FF decodes to the byte 0xFF) is refused naming it, its byte
// written as U+FFFD: the refusal's JSON once threw as it was written, and the client got no
// answer at all.
TEST(HttpHostile, AValueThatIsNotUtf8IsRefusedNamingIt) {
  Plant plant;
  httplib::Client& c = plant.client;
  const std::string fffd = "\xEF\xBF\xBD";
  const std::vector<std::pair<std::string, std::string>> asked = {
      {"/api/fillets?limit=%FF", "limit must be an integer (got '" + fffd + "')"},
      {"/api/fillets?decision=%FF%FE",
       "decision must be pass, reject or not_inspected (got '" + fffd + fffd + "')"},
      {"/api/fillets?limit=7%C3", "limit must be an integer (got '7" + fffd + "')"}};
  for (const auto& [path, said] : asked) {
    const auto r = c.Get(path);
    ASSERT_TRUE(r) << path << ": " << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 400) << path;
    const nlohmann::json j = nlohmann::json::parse(r->body, nullptr, false);
    ASSERT_TRUE(j.is_object()) << path << ": " << r->body;
    EXPECT_EQ(j.value("error", ""), said) << path;
  }
  const auto again = c.Get("/api/fillets?limit=3");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 200);
}

TEST(HttpHostile, AHeaderFloodIsRefused) {
  Plant plant;
  httplib::Client& c = plant.client;
  httplib::Headers many;
  for (int k = 0; k < 5000; ++k) many.emplace("X-Flood-" + std::to_string(k), "1");
  const auto r = c.Get("/api/statistics", many);
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  EXPECT_EQ(r->status, 431);
  // Refused at the gate (a head over 64 kB) or after parsing (over 100 headers).
  EXPECT_TRUE(r->body.find("more than 100 request headers") != std::string::npos ||
              r->body.find("request head larger than") != std::string::npos)
      << r->body;
  httplib::Headers hundreds;
  for (int k = 0; k < 300; ++k) hundreds.emplace("X-H-" + std::to_string(k), "1");
  const auto parsed = c.Get("/api/statistics", hundreds);
  ASSERT_TRUE(parsed);
  EXPECT_EQ(parsed->status, 431);
  EXPECT_NE(parsed->body.find("more than 100 request headers"), std::string::npos) << parsed->body;
  httplib::Headers few;
  for (int k = 0; k < 50; ++k) few.emplace("X-Some-" + std::to_string(k), "1");
  const auto ok = c.Get("/api/statistics", few);
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
}

TEST(HttpHostile, RefusedEventRequestsCloseTheirConnections) {
  test::TempDir dir;
  RangexServer server(default_plant_config(1), options(dir));
  HttpOptions ho = http_options();
  ho.max_event_streams = 1;  // a pool of 9 threads
  HttpServer web(server.engine(), server.store(), server.hub(), ho);
  // The one event stream there is room for, held open.
  std::atomic<bool> opened{false};
  std::thread holder([&] {
    httplib::Client c("127.0.0.1", web.port());
    c.set_read_timeout(60, 0);
    c.Get("/api/events", [&](const char*, size_t) {
      opened = true;
      return true;
    });
  });
  for (int k = 0; k < 500 && web.event_streams() < 1; ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(web.event_streams(), 1);
  // Twenty more, each refused, each from a client that would keep its connection alive.
  std::vector<std::unique_ptr<httplib::Client>> refused;
  for (int k = 0; k < 20; ++k) {
    refused.push_back(std::make_unique<httplib::Client>("127.0.0.1", web.port()));
    refused.back()->set_keep_alive(true);
    const auto r = refused.back()->Get("/api/events");
    ASSERT_TRUE(r) << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 503);
    EXPECT_EQ(r->get_header_value("Connection"), "close");
  }
  // The API still answers (a liveness check; the header above is what tells the client to
  // let its thread go: httplib's own client did not hold the threads here even without it,
  // the clients of the report did). The bound is for a hang, not for speed.
  httplib::Client c("127.0.0.1", web.port());
  c.set_read_timeout(4, 0);
  const auto st = c.Get("/api/statistics");
  ASSERT_TRUE(st) << httplib::to_string(st.error());
  EXPECT_EQ(st->status, 200);
  web.stop();  // ends the held stream
  holder.join();
}

// An export of more rows than two pages is sent a page at a time as the reader takes it
// (chunked): every row once, in order, and the download ends with its last chunk.
TEST(HttpHostile, AnExportOfSeveralPagesIsSentWholeAPageAtATime) {
  test::TempDir dir;
  RangexServer server{default_plant_config(1), options(dir)};
  HttpOptions ho = http_options();
  ho.csv_page = 100;  // pages of 100 rows: the store writes each row with an fsync
  HttpServer web{server.engine(), server.store(), server.hub(), ho};
  constexpr int kRows = 2 * 100 + 7;
  for (int i = 0; i < kRows; ++i) {
    StoredFillet f;
    f.lane = 0, f.lane_fillet = i, f.rows = 10, f.decided_ns = now_ns();
    f.decision = "pass", f.calibration_id = "cal";
    server.store().add_fillet(f);
  }
  httplib::Client c("127.0.0.1", web.port());
  const std::vector<std::string> lines = test::csv_export_lines(c, "/api/fillets.csv");
  ASSERT_EQ(lines.size(), size_t(kRows) + 1);
  EXPECT_EQ(lines[0].rfind("uid,", 0), 0u) << lines[0];
  for (int i = 0; i < kRows; ++i)  // uids count from 1, in the order they were stored
    ASSERT_EQ(lines[size_t(i) + 1].rfind(join(i + 1, ",0,", i, ","), 0), 0u)
        << lines[size_t(i) + 1];
}

// A listen address whose port is not a number is refused, naming it: std::stoi read
// "127.0.0.1:80x8" as port 80.
TEST(HttpHostile, AListenAddressWhosePortIsNotANumberIsRefused) {
  test::TempDir dir;
  RangexServer server{default_plant_config(1), options(dir)};
  for (const char* listen : {"127.0.0.1:80x8", "127.0.0.1:", "127.0.0.1:65536", "127.0.0.1:-1"}) {
    HttpOptions ho = http_options();
    ho.listen = listen;
    try {
      HttpServer web{server.engine(), server.store(), server.hub(), ho};
      ADD_FAILURE() << listen << " was taken (port " << web.port() << ")";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("'" + std::string(listen) +
                                           "': the port must be a number 0..65535"),
                std::string::npos)
          << e.what();
    }
  }
}
