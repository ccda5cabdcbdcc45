#include "fleet/fleet_server.h"

#include <httplib.h>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "fleet/fleet_records.h"
#include "plantdb/pg_pool.h"
#include "plantdb/plant_db_schema.h"
#include "service/gated_http_server.h"
#include "service/http_front.h"
#include "service/http_json.h"
#include "service/http_params.h"

namespace rangex {

using json = nlohmann::json;

FleetServer::FleetServer(FleetOptions opt) : opt_(std::move(opt)), access_(opt_.security) {
  if (opt_.conninfo.empty())
    fail("the fleet view needs plant.results_db: the plant-wide PostgreSQL it shows");
  check_listen_security(opt_.listen, opt_.security, "the fleet view");
  db_ = std::make_unique<PgPool>(opt_.conninfo, 4, 5, opt_.db_statement_timeout_s);
  {
    PgPool::Lease db = db_->take();
    require_plant_db_schema(*db);
  }
  HttpFront front = make_http_front(opt_.listen, opt_.security, 16, "the fleet view");
  host_ = front.host;
  guard_http(*front.server, access_);
  serve_dashboard_files(*front.server);
  plant_routes(*front.server);
  fillet_routes(*front.server);
  record_routes(*front.server);
  front.server->Get("/api/events", [](const httplib::Request&, httplib::Response&) {
    throw NotFound(
        "the fleet view has no live event stream: it reads PostgreSQL (each server's "
        "dashboard streams its own decisions)");
  });
  port_ = bind_http_front(front, opt_.listen, "the fleet view");
  http_ = std::move(front.server);
  listener_ = listen_in_background(*http_);
}

FleetServer::~FleetServer() {
  stop();
}

std::string FleetServer::address() const {
  return host_ + ":" + std::to_string(port_);
}

void FleetServer::stop() {
  if (stopping_.exchange(true)) return;
  http_->stop();
  http_->gate().stop();
  if (listener_.joinable()) listener_.join();
}

namespace {
json health_of(const FleetServerRow& r) {
  json h = json::parse(r.health.empty() ? "{}" : r.health, nullptr, false);
  return h.is_object() ? h : json::object();
}
}  // namespace

std::string FleetServer::server_state(const FleetServerRow& r, int64_t now) const {
  if (r.seen_ns <= 0) return "never heard from";
  const double silent = double(now - r.seen_ns) * 1e-9;
  if (silent > opt_.silent_after_s) return "silent for " + std::to_string(int64_t(silent)) + " s";
  // Heard from, and says it cannot inspect (a stalled worker, a failed store).
  const json h = health_of(r);
  if (!h.value("serving", true)) {
    std::string why;
    for (const json& w : h.value("not_serving_because", json::array()))
      if (w.is_string()) why += (why.empty() ? ": " : "; ") + w.get<std::string>();
    return "NOT SERVING" + why;
  }
  return "up";
}

namespace {
// A Prometheus sample line with the server's label (ids are letters, digits, '-_.').
void metric(std::string& out, const char* name, const std::string& server, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  out += std::string(name) + "{server=\"" + server + "\"} " + buf + "\n";
}
}  // namespace

void FleetServer::plant_routes(httplib::Server& s) {
  s.Get("/api/info", [this](const httplib::Request&, httplib::Response& res) {
    PgPool::Lease db = db_->take();
    const std::vector<FleetServerRow> rows = fleet_servers(*db);
    size_t lanes = 0;
    for (const FleetServerRow& r : rows) lanes += health_of(r).value("lanes", json::array()).size();
    send_json(res, {{"fleet", true},
                    {"version", opt_.version},
                    {"plant", opt_.plant},
                    {"servers", rows.size()},
                    {"lanes", lanes},
                    {"backend", "fleet view"},
                    {"database", db_->where()},
                    {"forwarding", nullptr},
                    {"now_ns", now_ns()}});
  });
  s.Get("/api/servers", [this](const httplib::Request&, httplib::Response& res) {
    PgPool::Lease db = db_->take();
    const int64_t now = now_ns();
    json out = json::array();
    for (const FleetServerRow& r : fleet_servers(*db)) {
      const json h = health_of(r);
      const std::string state = server_state(r, now);
      out.push_back({{"server", r.id},
                     {"host", r.host},
                     {"http", r.http},
                     {"state", state},
                     {"up", state == "up"},
                     {"started_ns", r.started_ns},
                     {"seen_ns", r.seen_ns},
                     {"head_seq", r.head_seq},
                     {"forwarded_seq", r.forwarded_seq},
                     {"lag_records", r.lag_records},
                     {"lag_seconds", r.lag_seconds},
                     {"version", h.value("version", "")},
                     {"backend", h.value("backend", "")},
                     {"warnings", h.value("warnings", json::array())}});
    }
    send_json(res, out);
  });
  s.Get("/api/lanes", [this](const httplib::Request&, httplib::Response& res) {
    PgPool::Lease db = db_->take();
    const int64_t now = now_ns();
    json out = json::array();
    for (const FleetServerRow& r : fleet_servers(*db)) {
      const std::string state = server_state(r, now);
      for (json lane : health_of(r).value("lanes", json::array())) {
        lane["server"] = r.id;
        lane["server_state"] = state;
        // The tile as its server last said; a server not heard from cannot vouch for it.
        if (state.rfind("NOT SERVING", 0) == 0)
          lane["light"] = "red", lane["light_reason"] = "server " + r.id + " " + state;
        else if (state != "up")
          lane["light"] = "red", lane["light_reason"] = "server " + r.id + " " + state +
                                                        " (its tile is as it last reported)";
        out.push_back(std::move(lane));
      }
    }
    send_json(res, out);
  });
  s.Get("/api/history", [this](const httplib::Request& req, httplib::Response& res) {
    const int64_t minutes = int_param(req.params, "minutes", 60, 1, 60);
    constexpr int64_t kMinute = 60'000'000'000;
    PgPool::Lease db = db_->take();
    json out = json::array();
    for (const FleetBucket& b : fleet_history(*db, now_ns() - minutes * kMinute, kMinute))
      out.push_back({{"t_ns", b.t_ns},
                     {"fillets_per_min", b.fillets},
                     {"rejects_per_min", b.rejects},
                     {"not_inspected_per_min", b.not_inspected}});
    send_json(res, {{"period_s", 60}, {"samples", out}});
  });
  s.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
    PgPool::Lease db = db_->take();
    const int64_t now = now_ns();
    std::string out =
        "# HELP rangex_fleet_server_up 1 while the server reports within the silence bound\n"
        "# TYPE rangex_fleet_server_up gauge\n";
    const std::vector<FleetServerRow> rows = fleet_servers(*db);
    for (const FleetServerRow& r : rows)
      metric(out, "rangex_fleet_server_up", r.id, server_state(r, now) == "up" ? 1 : 0);
    out +=
        "# HELP rangex_fleet_server_silent_seconds since the server last wrote its row\n"
        "# TYPE rangex_fleet_server_silent_seconds gauge\n";
    for (const FleetServerRow& r : rows)
      metric(out, "rangex_fleet_server_silent_seconds", r.id,
             r.seen_ns > 0 ? double(now - r.seen_ns) * 1e-9 : -1);
    out +=
        "# HELP rangex_fleet_forward_lag_records records stored on the server and not yet here\n"
        "# TYPE rangex_fleet_forward_lag_records gauge\n";
    for (const FleetServerRow& r : rows)
      metric(out, "rangex_fleet_forward_lag_records", r.id, double(r.lag_records));
    out +=
        "# HELP rangex_fleet_forward_lag_seconds age of the oldest record not yet here\n"
        "# TYPE rangex_fleet_forward_lag_seconds gauge\n";
    for (const FleetServerRow& r : rows)
      metric(out, "rangex_fleet_forward_lag_seconds", r.id, r.lag_seconds);
    res.set_content(out, "text/plain; version=0.0.4; charset=utf-8");
  });
}

}  // namespace rangex
