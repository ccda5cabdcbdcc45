// rangexd's HTTP side (plant.http, loopback by default): the operator's web dashboard
// (static files embedded in the binary), a JSON API over the same engine, store and results
// hub as the gRPC services, a live event stream of decisions (server-sent events, one
// bounded, lag-reporting hub subscription per client), and Prometheus metrics at /metrics.
//
// Endpoints (docs/dashboard.md):
//   GET /                          the dashboard (index.html, app.js, style.css)
//   GET /api/info                  plant, version, backend
//   GET /api/lanes                 per lane: state, rates, light, calibration
//   GET /api/statistics            the engine's statistics (as GetStatistics)
//   GET /api/history               the last hour, sampled every 2 s
//   GET /api/fillets               ?lane=&decision=&from_ns=&to_ns=&after=&limit=&newest=1
//   GET /api/fillets.csv           the same, every match, as CSV for an audit
//   GET /api/fillets/UID           one fillet with its fragments and images
//   GET /api/fillets/UID/images/K  K: overlay | xray | thickness | pseudo_xray | residual
//                                  (8-bit views; ?raw=1: the stored 16-bit record)
//   GET /api/calibrations          ?lane=: versions, and who uploaded/activated what when
//   GET /api/audit                 ?limit=: the audit log, newest last
//   GET /api/events                ?lanes=1,2&decisions=reject: server-sent events
//   POST /api/lanes/L/verification {"piece", "x_mm", "tolerance_mm", "fillets"}: starts a
//                                  verification run (operator role; JSON from this origin)
//   GET /metrics                   Prometheus text format
#pragma once
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "service/access_control.h"
#include "service/engine.h"
#include "service/fillet_csv.h"
#include "service/plant_history.h"

namespace httplib {
class Server;
struct Request;
struct Response;
}  // namespace httplib

namespace rangex {

class HttpGate;
struct EventClient;

struct HttpOptions {
  std::string listen = "127.0.0.1:8080";  // host:port; port 0 picks a free one
  int max_event_streams = 32;             // more are refused with 503
  double history_period_s = 2;            // the charts' sampling period
  int csv_page = kCsvPage;                // rows an export reads and holds at once
  std::string version = "rangex 0.1.0";
  // TLS and who may read (plant.yaml security): every endpoint needs the viewer role. A
  // client proves itself with a client certificate, or a token as "Bearer T" or as Basic's
  // password (browsers ask for it when answered 401).
  SecurityConfig security;
  // Counts the gRPC side knows (open ingest streams).
  std::function<int()> ingest_streams;
};

// What the fleet view shows of a server (its `servers` row): version, backend, whether it
// can inspect (and why not), its lanes as their dashboard tiles (rates from `h`) and its
// warnings, as JSON text.
std::string server_health_text(Engine& engine, PlantHistory& h, const std::string& version);

class HttpServer {
 public:
  // Binds (throws Error naming the address when it cannot) and serves on its own threads.
  HttpServer(Engine& engine, Store& store, ResultsHub& hub, HttpOptions opt);
  ~HttpServer();
  int port() const { return port_; }
  std::string address() const;  // host:port as bound
  bool tls() const { return opt_.security.tls(); }
  // Ends every event stream and stops serving (before the engine's drain).
  void stop();
  int event_streams() const { return event_streams_; }
  // This server's health for the fleet view (http_json.h: server_health_text), with the
  // tiles' rates from this dashboard's history.
  std::string health_text();
  // Where a browser or the fleet view reaches this dashboard: "http://host:port" (https
  // with TLS; the host name when it listens on every address).
  std::string url() const;
  // Event streams closed because they fell behind while another client asked for one.
  uint64_t event_streams_dropped() const { return events_dropped_; }

 private:
  void routes(httplib::Server& s);
  // The routes by resource (http_*_routes.cpp, http_events.cpp).
  void plant_routes(httplib::Server& s);
  void fillet_routes(httplib::Server& s);
  void record_routes(httplib::Server& s);
  void event_routes(httplib::Server& s);
  void lane_action_routes(httplib::Server& s);
  // Who sent the request: its verified client certificate, or its token.
  Identity identify(const httplib::Request& req) const;
  // Why a request that acts may not (another site's, or not JSON); "" when it may.
  std::string cross_site(const httplib::Request& req) const;
  void sampler();

  Engine& engine_;
  Store& store_;
  ResultsHub& hub_;
  HttpOptions opt_;
  AccessControl access_;
  PlantHistory history_;
  std::unique_ptr<httplib::Server> http_;
  std::string host_;
  int port_ = 0;
  std::thread listener_, sampler_;
  std::atomic<bool> stopping_{false};
  std::atomic<int> event_streams_{0};
  HttpGate* gate_ = nullptr;  // the gate in front of http_
  std::mutex events_mu_;
  std::vector<std::shared_ptr<EventClient>> event_clients_;  // oldest first
  std::atomic<uint64_t> events_dropped_{0};
};

}  // namespace rangex
