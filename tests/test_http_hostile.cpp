// The HTTP side against requests a plant's network can hold (issue 24): multi-range bombs and
// header floods are refused small and fast, and the dashboard's API answers throughout.
#include <gtest/gtest.h>
#include <httplib.h>

#include <string>

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
