// The fleet view (rangexd --fleet): the dashboard and its JSON API over the plant-wide
// PostgreSQL, for every lane of every server that forwards there (docs/plant-wide.md).
// Read-only: acting on a lane (a verification run, a calibration) is done on its server.
// Images stay with the server that took them and are fetched through it.
//
// Endpoints (as rangexd's dashboard's, with the server named):
//   GET /api/info                      {"fleet": true, plant, servers, lanes, database}
//   GET /api/servers                   each server: state (up | silent), lag, warnings
//   GET /api/lanes                     every server's lane tiles, grouped by server
//   GET /api/fillets                   ?server=&lane=&decision=&from_ns=&to_ns=&after=&limit=
//                                      &newest=1, ordered by (decided_ns, server, uid)
//   GET /api/fillets.csv               every match, with a server column
//   GET /api/fillets/SERVER/UID        one fillet, its images and which server keeps them
//   GET /api/fillets/SERVER/UID/images/K   fetched from SERVER's dashboard (502 naming it
//                                      when it cannot be reached)
//   GET /api/calibrations              ?lane=: calibration and learned-settings versions of
//                                      every server, and who did what when
//   GET /api/audit                     ?limit=: every server's audit log, newest last
//   GET /api/history                   fillets, rejects per minute over the last hour
//   GET /metrics                       per server: up, lag in records and seconds
#pragma once
#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include "core/security_config.h"
#include "service/access_control.h"

namespace httplib {
class Server;
struct Request;
}  // namespace httplib

namespace rangex {

class GatedHttpServer;
class PgPool;
struct FleetServerRow;

struct FleetOptions {
  std::string conninfo;  // plant.results_db
  std::string listen = "127.0.0.1:8090";
  std::string plant = "plant";
  std::string version = "rangex 0.1.0";
  SecurityConfig security;     // who may read, and TLS (plant.yaml security), as rangexd's
  double silent_after_s = 15;  // a server not heard from for longer is shown silent
  double image_timeout_s = 5;  // fetching an image from its server
  // A statement of the plant-wide database; one that has no answer 5 s later is a page
  // that names the database (503), not a reader kept waiting.
  int db_statement_timeout_s = 10;
  std::string servers_ca;  // verifies servers' https dashboards (empty: system CAs)
};

class FleetServer {
 public:
  // Connects once to check the schema (throws FailedPrecondition naming the migration to
  // run), binds (throws Error naming the address) and serves on its own threads.
  explicit FleetServer(FleetOptions opt);
  ~FleetServer();
  int port() const { return port_; }
  std::string address() const;
  bool tls() const { return opt_.security.tls(); }
  void stop();

 private:
  void plant_routes(httplib::Server& s);   // info, servers, lanes, history, metrics
  void fillet_routes(httplib::Server& s);  // fillets, csv, one fillet, its images
  void record_routes(httplib::Server& s);  // calibrations, audit
  // "up", or why not ("silent for 42 s", "never heard from").
  std::string server_state(const FleetServerRow& r, int64_t now) const;

  FleetOptions opt_;
  AccessControl access_;
  std::unique_ptr<PgPool> db_;
  std::unique_ptr<GatedHttpServer> http_;
  std::string host_;
  int port_ = 0;
  std::thread listener_;
  std::atomic<bool> stopping_{false};
};

}  // namespace rangex
