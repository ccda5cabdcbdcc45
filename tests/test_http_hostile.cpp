// The HTTP side against requests a plant's network can hold (issue 24): multi-range bombs and
// header floods are refused small and fast, and the dashboard's API answers throughout.
#include <gtest/gtest.h>
#include <httplib.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "core/plant_config.h"
#include "service/http_server.h"
#include "service/server.h"
#include "temp_dir.h"

using namespace rangex;

namespace {

ServerOptions options(const test::TempDir& t) {
  ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.data_dir = t.str("data");
  o.engine.backend.name = "cpu";
  return o;
}

HttpOptions http_options() {
  HttpOptions ho;
  ho.listen = "127.0.0.1:0";
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

}  // namespace

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

TEST(HttpHostile, AHeaderFloodIsRefused) {
  Plant plant;
  httplib::Client& c = plant.client;
  httplib::Headers many;
  for (int k = 0; k < 5000; ++k) many.emplace("X-Flood-" + std::to_string(k), "1");
  const auto r = c.Get("/api/statistics", many);
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  EXPECT_EQ(r->status, 431);
  EXPECT_NE(r->body.find("more than 100 request headers"), std::string::npos) << r->body;
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
