// rangexd's gRPC server: the four rangex.v1 services over one Engine, with standard health
// checking (per service: "", rangex.v1.IngestService, ResultsService, CalibrationService,
// ControlService) and server reflection. A watchdog thread turns the engine's health into
// grpc.health.v1 statuses and, after exit_after_s of NOT_SERVING, calls on_fatal so that
// rangexd can exit for its supervisor to restart it. A retention thread prunes the store
// (plant.yaml retention) at start and every retention.every_h.
#pragma once
#include <atomic>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "core/plant_config.h"
#include "plc/plc_release.h"
#include "sensors/sensor_ingest.h"
#include "service/engine.h"

namespace grpc {
class Server;
}

namespace rangex {

class Forwarder;

struct StreamCounters;
class AccessControl;
class RpcServices;

struct ServerOptions {
  std::string listen;    // host:port; empty takes plant.yaml's
  std::string data_dir;  // empty takes plant.yaml's storage
  EngineOptions engine;
  // The largest message gRPC takes; 0: from the plant's lanes (line_shape.h), so that an
  // oversized line is refused in-band and one far larger ends its call before it is parsed.
  int max_message_bytes = 0;
  // Connections older than this are closed (GOAWAY) after a grace period; feeders reconnect.
  // 0: never. Useful behind load balancers, and how tests drop connections.
  int max_connection_age_ms = 0;
  // Keepalive. The least interval between a client's pings that is accepted, with or without
  // calls (gRPC's default is 5 minutes, and a client pinging faster is cut off with GOAWAY
  // "too_many_pings", a dashboard's quiet subscription with it); rangex clients ping every
  // 10 s (client/channel.h). And how often the server pings a quiet client, to notice one
  // that is gone.
  int min_ping_interval_ms = 5000;
  int keepalive_ms = 60000;
  double watchdog_period_s = 0.1;
  // Freed heap given back to the system this often, large blocks kept out of malloc's arenas
  // (heap_trim.h); 0: neither.
  double heap_trim_s = 60;
  std::function<void(const Health&)> on_fatal;  // NOT_SERVING for exit_after_s
  SensorOptions sensors;  // lanes fed by their own GigE Vision devices (plant.yaml sources)
  // Sees every line a lane's sensors make, before the engine does (tests compare the lines
  // that came over GigE Vision with a replay of the same lines).
  std::function<void(const IncomingLine&)> sensor_tap;
};

// A stored decision as the PLC's release of it (rejects and uninspected fillets are sent too,
// for the PLC's record; only a pass lets a fillet through).
Release release_of(const StoredFillet& s);

class RangexServer {
 public:
  RangexServer(const PlantConfig& plant, ServerOptions opt);
  ~RangexServer();
  int port() const { return port_; }
  std::string address() const;
  // Graceful: stops taking lines (handed back), drains and decides everything queued,
  // flushes the store, and closes the fillets still coming in (the end of a recording) or
  // hands them back undecided (rangexd's stop: the feeders resend their lines to the next
  // server). False when the queue could not be drained within the engine's drain_timeout_s.
  bool shutdown(OpenFillets open = OpenFillets::kClose);
  void wait();
  Engine& engine() { return *engine_; }
  // The lanes fed by their sensors, with every device's state and counters.
  std::vector<LaneSensors> sensors() const;
  // The PLC link (plant.yaml plc); enabled false without one.
  PlcStatus plc() const;
  Store& store() { return *store_; }
  ResultsHub& hub() { return *hub_; }
  int ingest_streams() const;
  // With a plant-wide database: where this server's dashboard serves and its health (JSON
  // text), for the fleet view (written to its `servers` row at each heartbeat).
  void describe_for_fleet(const std::string& http_url, std::function<std::string()> health);
  // Resident bytes given back by the periodic heap trims since start.
  size_t heap_returned() const { return heap_returned_; }

 private:
  // With a plant-wide database: lanes another server ran last go on from its records.
  void continue_moved_lanes();
  void watchdog();
  void retention();  // a pass at start, then every retention.every_h
  void set_health(const Health& h);
  std::vector<PlcLaneView> plc_lanes();  // belt counts and PackML states for the PLC

  PlantConfig plant_;
  ServerOptions opt_;
  std::unique_ptr<Store> store_;
  std::unique_ptr<ResultsHub> hub_;
  std::unique_ptr<PlcRelease> plc_;  // outlives the engine, whose inspectors queue into it
  std::unique_ptr<Engine> engine_;
  std::unique_ptr<Forwarder> forwarder_;  // with plant.results_db: the store to PostgreSQL
  std::unique_ptr<SensorIngest> sensors_;
  std::unique_ptr<StreamCounters> counters_;
  std::unique_ptr<AccessControl> access_;
  std::unique_ptr<RpcServices> services_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  int64_t started_ns_ = 0;
  bool down_ = false;

  std::thread watchdog_, retention_;
  std::mutex wd_mu_;
  std::condition_variable wd_cv_;
  bool wd_stop_ = false;
  std::atomic<size_t> heap_returned_{0};
};

}  // namespace rangex
