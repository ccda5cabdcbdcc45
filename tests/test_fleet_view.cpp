// The fleet view (rangexd --fleet) against a real PostgreSQL (tests/pg_instance.h): who may
// read it (TLS, client certificates, tokens, as rangexd's dashboard), images fetched through
// the server that keeps them with the reader's credentials, a server that is down or silent
// named as such, hostile paging, and a database whose schema is behind.
#include <gtest/gtest.h>
#include <httplib.h>

#include <cstdlib>
#include <future>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "core/error.h"
#include "csv_export.h"
#include "fleet/fleet_server.h"
#include "pg_instance.h"
#include "plantdb/forwarder.h"
#include "plantdb/pg_connection.h"
#include "plantdb/plant_db_schema.h"
#include "service/fillet_csv.h"
#include "store/sha256_hex.h"
#include "store/store.h"
#include "temp_dir.h"
#include "test_ca.h"
#include "wait_until.h"

using namespace rangex;
using json = nlohmann::json;
using rangex::test::PgInstance;
using rangex::test::TempDir;

namespace {

const char* kViewerToken = "rgx_fleet-viewer-token";
const char* kStaleToken = "rgx_not-a-listed-token";

// One migrated database with server "srv-a"'s records (three fillets, one a reject with an
// overlay) forwarded by the real forwarder.
struct Plant {
  PgInstance pg;
  TempDir dir;
  int64_t reject_uid = 0;
  Plant() {
    PgConnection db(pg.conninfo());
    plant_db_migrate(db);
    Store store(dir.str("a"));
    for (int i = 0; i < 3; ++i) {
      StoredFillet f;
      f.lane = 1, f.lane_fillet = i, f.rows = 100, f.decided_ns = now_ns();
      f.decision = i == 1 ? "reject" : "pass";
      f.calibration_id = "cal";
      const int64_t uid = store.add_fillet(f);
      if (i == 1) {
        reject_uid = uid;
        store.add_image(uid, "overlay", store.image_dir(uid) + "/overlay.png");
      }
    }
    ForwarderOptions o;
    o.conninfo = pg.conninfo();
    o.server_id = "srv-a";
    o.idle_s = 0.05;
    Forwarder fw(store, o);
    fw.start();
    EXPECT_TRUE(fw.wait_caught_up(60));
    fw.stop();
  }
  void set_server(const std::string& http, int64_t seen_ns) {
    PgConnection db(pg.conninfo());
    db.exec("UPDATE servers SET http = $1, seen_ns = $2, health = $3 WHERE server_id = 'srv-a'",
            {http, std::to_string(seen_ns), R"({"lanes": [{"lane": 1, "light": "green"}]})"});
  }
};

FleetOptions secured(const Plant& p) {
  FleetOptions o;
  o.conninfo = p.pg.conninfo();
  o.listen = "127.0.0.1:0";
  SecurityConfig& s = o.security;
  s.tls_cert = test::test_ca("server.crt");
  s.tls_key = test::test_ca("server.key");
  s.client_ca = test::test_ca("ca.crt");
  s.identities = {{"viewer-1", Role::viewer}, {"admin-1", Role::admin}};
  s.tokens = {{"qa-screen", Role::viewer, sha256_hex(kViewerToken)}};
  return o;
}

std::unique_ptr<httplib::SSLClient> client(int port, const std::string& cert = "") {
  auto c = cert.empty()
               ? std::make_unique<httplib::SSLClient>("127.0.0.1", port)
               : std::make_unique<httplib::SSLClient>(
                     "127.0.0.1", port, test::test_ca(cert + ".crt"), test::test_ca(cert + ".key"));
  c->set_ca_cert_path(test::test_ca("ca.crt").c_str());
  c->enable_server_certificate_verification(true);
  c->set_read_timeout(30, 0);
  return c;
}

int status_of(httplib::SSLClient& c, const std::string& path, const std::string& token = "") {
  httplib::Headers h;
  if (!token.empty()) h.emplace("Authorization", "Bearer " + token);
  const auto r = c.Get(path.c_str(), h);
  return r ? r->status : -1;
}

}  // namespace

TEST(FleetView, ReadersNeedTheViewerRoleAsOnTheDashboard) {
  Plant p;
  p.set_server("", now_ns());
  FleetServer fleet(secured(p));
  for (const char* path : {"/", "/api/info", "/api/fillets", "/api/servers", "/metrics"}) {
    SCOPED_TRACE(path);
    EXPECT_EQ(status_of(*client(fleet.port()), path), 401);  // anonymous: none
    EXPECT_EQ(status_of(*client(fleet.port()), path, kStaleToken), 401);
    EXPECT_EQ(status_of(*client(fleet.port(), "stranger-1"), path), 403);  // no role
    EXPECT_EQ(status_of(*client(fleet.port()), path, kViewerToken), 200);
    EXPECT_EQ(status_of(*client(fleet.port(), "viewer-1"), path), 200);
  }
  httplib::Client plain("127.0.0.1", fleet.port());
  plain.set_read_timeout(5, 0);
  const auto r = plain.Get("/api/info");
  EXPECT_TRUE(!r || r->status == 400) << "plaintext to a TLS fleet view must not be served";
  // The fleet is read-only: nothing acts on a lane through it.
  auto c = client(fleet.port(), "admin-1");
  const auto post =
      c->Post("/api/lanes/1/verification", R"({"piece": "x", "x_mm": 1})", "application/json");
  ASSERT_TRUE(post);
  EXPECT_EQ(post->status, 404);
}

TEST(FleetView, ImagesComeFromTheServerThatKeepsThemWithTheReadersCredentials) {
  Plant p;
  // The server's dashboard, as far as the fleet sees it: what it asks and what it gets.
  httplib::Server dashboard;
  std::string asked_path, asked_auth;
  dashboard.Get(R"(/api/fillets/(\d+)/images/([a-z_]+))",
                [&](const httplib::Request& req, httplib::Response& res) {
                  asked_path = req.path + (req.has_param("raw") ? "?raw=1" : "");
                  asked_auth = req.get_header_value("Authorization");
                  res.set_content(std::string("\x89PNG fake bytes\0\1", 17), "image/png");
                });
  const int port = dashboard.bind_to_any_port("127.0.0.1");
  std::thread serving([&] { dashboard.listen_after_bind(); });
  p.set_server("http://127.0.0.1:" + std::to_string(port), now_ns());
  FleetServer fleet(secured(p));
  auto c = client(fleet.port());
  httplib::Headers h{{"Authorization", std::string("Bearer ") + kViewerToken}};
  const std::string base = "/api/fillets/srv-a/" + std::to_string(p.reject_uid);
  const auto got = c->Get((base + "/images/overlay").c_str(), h);
  ASSERT_TRUE(got);
  EXPECT_EQ(got->status, 200);
  EXPECT_EQ(got->body, std::string("\x89PNG fake bytes\0\1", 17));
  EXPECT_EQ(asked_path, "/api/fillets/" + std::to_string(p.reject_uid) + "/images/overlay");
  EXPECT_EQ(asked_auth, std::string("Bearer ") + kViewerToken);
  ASSERT_TRUE(c->Get((base + "/images/overlay?raw=1").c_str(), h));
  EXPECT_EQ(asked_path, "/api/fillets/" + std::to_string(p.reject_uid) + "/images/overlay?raw=1");
  // A kind the server does not keep, or a fillet it does not have, is not asked for.
  asked_path.clear();
  const auto none = c->Get((base + "/images/xray").c_str(), h);
  ASSERT_TRUE(none);
  EXPECT_EQ(none->status, 404);
  EXPECT_NE(none->body.find("keeps no xray image"), std::string::npos) << none->body;
  EXPECT_EQ(c->Get("/api/fillets/srv-a/999999/images/overlay", h)->status, 404);
  EXPECT_EQ(c->Get("/api/fillets/srv-z/1/images/overlay", h)->status, 404);
  EXPECT_TRUE(asked_path.empty());
  dashboard.stop();
  serving.join();
  // Down: the fleet names the server and where it should have been.
  const auto down = c->Get((base + "/images/overlay").c_str(), h);
  ASSERT_TRUE(down);
  EXPECT_EQ(down->status, 502);
  const json why = json::parse(down->body);
  EXPECT_EQ(why["server"], "srv-a");
  EXPECT_TRUE(why["unreachable"].get<bool>());
  EXPECT_NE(why["error"].get<std::string>().find(
                "srv-a at http://127.0.0.1:" + std::to_string(port) + " is unreachable"),
            std::string::npos)
      << down->body;
  // No dashboard at all (plant.http off): said so, not a broken image.
  p.set_server("", now_ns());
  const auto off = c->Get((base + "/images/overlay").c_str(), h);
  ASSERT_TRUE(off);
  EXPECT_EQ(off->status, 503);
  EXPECT_NE(off->body.find("serves no dashboard"), std::string::npos) << off->body;
}

TEST(FleetView, AnHttpsDashboardIsVerifiedAgainstTheServersCa) {
  Plant p;
  httplib::SSLServer dashboard(test::test_ca("server.crt").c_str(),
                               test::test_ca("server.key").c_str());
  dashboard.Get(R"(/api/fillets/(\d+)/images/overlay)",
                [](const httplib::Request&, httplib::Response& res) {
                  res.set_content("tls bytes", "image/png");
                });
  const int port = dashboard.bind_to_any_port("127.0.0.1");
  std::thread serving([&] { dashboard.listen_after_bind(); });
  p.set_server("https://127.0.0.1:" + std::to_string(port), now_ns());
  const std::string path = "/api/fillets/srv-a/" + std::to_string(p.reject_uid) + "/images/overlay";
  httplib::Headers h{{"Authorization", std::string("Bearer ") + kViewerToken}};
  {
    FleetOptions o = secured(p);
    o.servers_ca = test::test_ca("ca.crt");
    FleetServer fleet(o);
    const auto got = client(fleet.port())->Get(path.c_str(), h);
    ASSERT_TRUE(got);
    EXPECT_EQ(got->status, 200) << got->body;
    EXPECT_EQ(got->body, "tls bytes");
  }
  {
    // A CA that did not sign the server's certificate: not fetched, and said so.
    FleetOptions o = secured(p);
    o.servers_ca = test::test_ca("rogue-ca.crt");
    FleetServer fleet(o);
    const auto got = client(fleet.port())->Get(path.c_str(), h);
    ASSERT_TRUE(got);
    EXPECT_EQ(got->status, 502);
    EXPECT_NE(got->body.find("srv-a at https://127.0.0.1"), std::string::npos) << got->body;
  }
  dashboard.stop();
  serving.join();
}

TEST(FleetView, ASilentServerIsShownSilentAndItsTilesRed) {
  Plant p;
  p.set_server("", now_ns() - int64_t(60e9));
  FleetOptions o = secured(p);
  o.security = SecurityConfig{};  // loopback, no authentication
  FleetServer fleet(o);
  httplib::Client c("127.0.0.1", fleet.port());
  const json servers = json::parse(c.Get("/api/servers")->body);
  ASSERT_EQ(servers.size(), 1u);
  EXPECT_FALSE(servers[0]["up"].get<bool>());
  EXPECT_EQ(servers[0]["state"].get<std::string>().rfind("silent for 6", 0), 0u)
      << servers[0]["state"];
  const json lanes = json::parse(c.Get("/api/lanes")->body);
  ASSERT_EQ(lanes.size(), 1u);
  EXPECT_EQ(lanes[0]["server"], "srv-a");
  EXPECT_EQ(lanes[0]["light"], "red");
  EXPECT_NE(lanes[0]["light_reason"].get<std::string>().find("server srv-a silent"),
            std::string::npos);
  EXPECT_NE(c.Get("/metrics")->body.find("rangex_fleet_server_up{server=\"srv-a\"} 0"),
            std::string::npos);
  p.set_server("", now_ns());
  EXPECT_TRUE(json::parse(c.Get("/api/servers")->body)[0]["up"].get<bool>());
  // Heard from, but it says it cannot inspect: its tiles are red with its reason.
  PgConnection(p.pg.conninfo())
      .exec(R"(UPDATE servers SET health = '{"serving": false, "not_serving_because": ["the store )"
            R"(failed: disk full"], "lanes": [{"lane": 1, "light": "green"}]}')");
  const json down = json::parse(c.Get("/api/servers")->body)[0];
  EXPECT_FALSE(down["up"].get<bool>());
  EXPECT_EQ(down["state"], "NOT SERVING: the store failed: disk full");
  EXPECT_EQ(json::parse(c.Get("/api/lanes")->body)[0]["light_reason"],
            "server srv-a NOT SERVING: the store failed: disk full");
}

TEST(FleetView, HostileQueriesAreRefusedByName) {
  Plant p;
  FleetOptions o = secured(p);
  o.security = SecurityConfig{};
  FleetServer fleet(o);
  httplib::Client c("127.0.0.1", fleet.port());
  for (const char* q :
       {"/api/fillets?after=12", "/api/fillets?after=x.srv-a.1", "/api/fillets?after=1.srv-a.-5",
        "/api/fillets?limit=0", "/api/fillets?lane=abc", "/api/fillets?decision=maybe"}) {
    SCOPED_TRACE(q);
    const auto r = c.Get(q);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400);
    EXPECT_NE(r->body.find("\"error\""), std::string::npos);
  }
  const auto quoted = c.Get("/api/fillets?server=x'%20OR%20'1'='1");
  ASSERT_TRUE(quoted);
  EXPECT_EQ(quoted->status, 200);
  EXPECT_EQ(json::parse(quoted->body)["fillets"].size(), 0u);
  EXPECT_EQ(c.Get("/api/events")->status, 404);
}

// A database host that takes connections and answers nothing (every PostgreSQL process
// stopped), read by 40 dashboards at once, more than the view's 16 threads: each is told
// so (503, naming the database) instead of waiting until its client gives up, and once the
// database answers, so does the view.
TEST(FleetView, AHungDatabaseIsNamedToEachReaderAndTheViewAnswersWhenItDoes) {
  Plant p;
  FleetOptions o = secured(p);
  o.security = SecurityConfig{};
  o.db_statement_timeout_s = 1;  // an answer is waited for 6 s
  FleetServer fleet(o);
  {
    httplib::Client c("127.0.0.1", fleet.port());
    ASSERT_EQ(c.Get("/api/servers")->status, 200);  // the pool keeps this connection
  }
  p.pg.freeze();
  std::vector<std::future<std::pair<int, std::string>>> readers;
  for (int i = 0; i < 40; ++i)
    readers.push_back(std::async(std::launch::async, [&, i] {
      httplib::Client c("127.0.0.1", fleet.port());
      c.set_read_timeout(60, 0);  // the bound: a reader held this long fails the test
      const auto r = c.Get(i % 2 ? "/api/servers" : "/metrics");
      return r ? std::make_pair(r->status, r->body)
               : std::make_pair(-1, "no answer: " + httplib::to_string(r.error()));
    }));
  std::vector<std::pair<int, std::string>> got;
  for (auto& r : readers) got.push_back(r.get());
  p.pg.thaw();
  int unanswered = 0;
  for (const auto& [status, body] : got) {
    EXPECT_EQ(status, 503) << body;
    EXPECT_NE(body.find("PostgreSQL at " + pg_where(p.pg.conninfo()) + ": "), std::string::npos)
        << body;
    unanswered += body.find("no answer within 6 s") != std::string::npos;
  }
  EXPECT_GE(unanswered, 1) << "the statement that waited was not named";
  httplib::Client c("127.0.0.1", fleet.port());
  EXPECT_TRUE(test::wait_until(30, [&] {
    const auto r = c.Get("/api/servers");
    return r && r->status == 200;
  })) << "the view did not answer again once the database did";
}

// An export across servers of more rows than two pages is sent a page at a time, each page
// read with a connection of its own: every row once, ordered by decision time, then server.
TEST(FleetView, AnExportOfSeveralPagesHasEveryRowOnceInOrder) {
  Plant p;
  constexpr int kRows = 2 * kCsvPage + 7;
  PgConnection(p.pg.conninfo())
      .exec(
          "INSERT INTO fillets (server_id, uid, lane, lane_fillet, first_encoder, rows, "
          "decision, reason, calibration_id, decided_ns, day) SELECT 'srv-b', g, 2, g, 0, 10, "
          "'pass', '', 'cal', t.ns + g, t.day FROM (SELECT max(decided_ns) AS ns, max(day) AS "
          "day FROM fillets) t, generate_series(1, " +
          std::to_string(kRows) + ") g");
  FleetOptions o = secured(p);
  o.security = SecurityConfig{};
  FleetServer fleet(o);
  httplib::Client c("127.0.0.1", fleet.port());
  const std::vector<std::string> lines = test::csv_export_lines(c, "/api/fillets.csv");
  ASSERT_EQ(lines.size(), size_t(kRows) + 4);  // the header, srv-a's three, srv-b's
  EXPECT_EQ(lines[0].rfind("server,uid,", 0), 0u) << lines[0];
  for (int i = 1; i <= 3; ++i)
    EXPECT_EQ(lines[size_t(i)].rfind("srv-a,", 0), 0u) << lines[size_t(i)];
  for (int g = 1; g <= kRows; ++g)
    ASSERT_EQ(lines[size_t(g) + 3].rfind("srv-b," + std::to_string(g) + ",2,", 0), 0u)
        << lines[size_t(g) + 3];
}

TEST(FleetView, ADatabaseBehindTheBuildsSchemaIsRefusedWithTheCommandToRun) {
  PgInstance pg;
  FleetOptions o;
  o.conninfo = pg.conninfo();
  o.listen = "127.0.0.1:0";
  try {
    FleetServer fleet(o);
    FAIL() << "an unmigrated database was served";
  } catch (const FailedPrecondition& e) {
    EXPECT_NE(std::string(e.what()).find("rangexctl db migrate"), std::string::npos) << e.what();
  }
  o.conninfo.clear();
  EXPECT_THROW(FleetServer{o}, Error);
}
