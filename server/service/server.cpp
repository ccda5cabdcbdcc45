#include "service/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/resource_quota.h>

#include <chrono>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/heap_trim.h"
#include "core/log.h"
#include "plantdb/forwarder.h"
#include "plantdb/lane_handover.h"
#include "plantdb/pg_connection.h"
#include "plantdb/plant_db_schema.h"
#include "rangex/v1/decision_names.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "service/access_control.h"
#include "service/line_shape.h"
#include "service/rpc_services.h"
#include "service/streams.h"

namespace rangex {

namespace {

constexpr const char* kServices[] = {"rangex.v1.IngestService", "rangex.v1.ResultsService",
                                     "rangex.v1.CalibrationService", "rangex.v1.ControlService"};

std::string read_pem(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("security.tls.", what, ": cannot read ", path);
  std::stringstream ss;
  ss << in.rdbuf();
  if (ss.str().find("-----BEGIN ") == std::string::npos)
    fail("security.tls.", what, ": ", path, " is not PEM");
  return ss.str();
}

std::shared_ptr<grpc::ServerCredentials> server_credentials(const SecurityConfig& s) {
  if (!s.tls()) return grpc::InsecureServerCredentials();
  // A client certificate is asked for and verified when presented; a client without one may
  // still prove itself with a token, or is refused per call with a message saying so.
  grpc::SslServerCredentialsOptions o(s.client_ca.empty()
                                          ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                          : GRPC_SSL_REQUEST_CLIENT_CERTIFICATE_AND_VERIFY);
  if (!s.client_ca.empty()) o.pem_root_certs = read_pem(s.client_ca, "client_ca");
  o.pem_key_cert_pairs.push_back({read_pem(s.tls_key, "key"), read_pem(s.tls_cert, "cert")});
  return grpc::SslServerCredentials(o);
}

}  // namespace

RangexServer::RangexServer(const PlantConfig& plant, ServerOptions opt)
    : plant_(plant), opt_(std::move(opt)) {
  if (opt_.listen.empty()) opt_.listen = plant_.listen;
  if (opt_.data_dir.empty()) opt_.data_dir = plant_.storage;
  if (opt_.max_message_bytes <= 0) {
    std::vector<LaneShape> shapes;
    for (const LaneConfig& l : plant_.lanes)
      shapes.push_back({l.id, l.frame_width, l.frame_height, l.xray.pixels, l.xray.energies});
    opt_.max_message_bytes = max_message_bytes(shapes);
  }
  check_listen_security(opt_.listen, plant_.security, "gRPC");
  if (opt_.heap_trim_s > 0) set_server_heap_policy();
  started_ns_ = now_ns();
  store_ = std::make_unique<Store>(opt_.data_dir);
  if (!plant_.results_db.empty()) continue_moved_lanes();
  hub_ = std::make_unique<ResultsHub>();
  if (plant_.plc.enabled()) {
    PlcHooks hooks;
    hooks.lanes = [this] { return plc_lanes(); };
    hooks.audit = [this](const std::string& what, const std::string& detail) {
      store_->audit("plc", what, detail);
    };
    plc_ = std::make_unique<PlcRelease>(plant_, std::move(hooks));
    opt_.engine.on_decided = [this](const StoredFillet& s) { plc_->decided(release_of(s)); };
  }
  engine_ = std::make_unique<Engine>(plant_, *store_, *hub_, opt_.engine);
  if (!plant_.results_db.empty()) {
    // Everything stored goes on to the plant-wide database once it is durable here;
    // inspection never waits for it (docs/plant-wide.md).
    ForwarderOptions fo;
    fo.conninfo = plant_.results_db;
    fo.server_id = plant_.server_id.empty() ? host_name() : plant_.server_id;
    fo.host = host_name();
    fo.retry_max_s = plant_.results_db_retry_max_s;
    forwarder_ = std::make_unique<Forwarder>(*store_, fo);
    engine_->set_forward_status([this] { return forwarder_->status(); });
    forwarder_->start();
  }
  if (plc_) {
    engine_->set_plc_status([this] { return plc_->status(); });
    plc_->start();
  }
  if (has_sensor_lanes(plant_))
    sensors_ = std::make_unique<SensorIngest>(
        plant_,
        [this](int lane) {
          LaneSink sink;
          sink.line = [this](IncomingLine&& in) {
            if (opt_.sensor_tap) opt_.sensor_tap(in);
            return engine_->submit(std::move(in)).accepted;
          };
          sink.lost = [this, lane](const std::string& why) { engine_->sensor_lost(lane, why); };
          return sink;
        },
        opt_.sensors);
  if (sensors_) engine_->set_sensor_states([this] { return sensors_->state(); });
  counters_ = std::make_unique<StreamCounters>();
  access_ = std::make_unique<AccessControl>(plant_.security);
  services_ = std::make_unique<RpcServices>(*access_, *engine_, *store_, *hub_, *counters_, opt_,
                                            started_ns_);
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder b;
  b.AddListeningPort(opt_.listen, server_credentials(plant_.security), &port_);
  // gRPC binds with SO_REUSEPORT by default: a second rangexd on this address would start
  // and take half of the clients' connections. It must fail to listen instead.
  b.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  b.SetMaxReceiveMessageSize(opt_.max_message_bytes);
  // The size check comes only once a message is whole: the quota is what bounds memory.
  grpc::ResourceQuota quota("rangexd-grpc");
  quota.Resize(size_t(opt_.engine.grpc_memory_mb) << 20);
  b.SetResourceQuota(quota);
  b.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS,
                       opt_.min_ping_interval_ms);
  b.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  b.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, opt_.keepalive_ms);
  b.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 20000);
  b.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  if (opt_.max_connection_age_ms > 0) {
    b.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_MS, opt_.max_connection_age_ms);
    b.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_GRACE_MS, opt_.max_connection_age_ms);
  }
  services_->register_with(b);
  server_ = b.BuildAndStart();
  if (!server_ || port_ == 0) {
    engine_->drain_and_stop();
    fail("cannot listen on ", opt_.listen,
         " (in use, e.g. by another rangexd, or no such address)");
  }
  set_health(engine_->health());
  store_->audit("rangexd", "server.start", "listening on " + address());
  watchdog_ = std::thread([this] { watchdog(); });
  retention_ = std::thread([this] { retention(); });
}

RangexServer::~RangexServer() {
  shutdown();
  engine_->set_sensor_states(nullptr);  // the ingest goes first
}

Release release_of(const StoredFillet& s) {
  Release r;
  r.uid = s.uid;
  r.lane = s.lane;
  r.first_encoder = s.first_encoder;
  r.last_encoder = s.first_encoder + std::max(0, s.rows - 1);
  // Anything but a pass or a reject is diverted as not inspected.
  const v1::Decision d = decision_from_name(s.decision);
  r.code = d == v1::DECISION_PASS     ? ReleaseCode::kPass
           : d == v1::DECISION_REJECT ? ReleaseCode::kReject
                                      : ReleaseCode::kNotInspected;
  return r;
}

std::string RangexServer::address() const {
  const auto colon = opt_.listen.rfind(':');
  return opt_.listen.substr(0, colon) + ":" + std::to_string(port_);
}

int RangexServer::ingest_streams() const {
  return counters_->ingest;
}

void RangexServer::set_health(const Health& h) {
  auto* hc = server_->GetHealthCheckService();
  hc->SetServingStatus("", h.serving);
  hc->SetServingStatus(kServices[0], h.serving);  // ingest: lines can be inspected
  hc->SetServingStatus(kServices[1], h.store_ok);
  hc->SetServingStatus(kServices[2], h.store_ok);
  hc->SetServingStatus(kServices[3], true);  // control: where to find out why
}

void RangexServer::watchdog() {
  bool serving = true, store_ok = true;
  auto unhealthy_since = std::chrono::steady_clock::time_point::min();
  bool fatal_called = false;
  auto trimmed_at = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(wd_mu_);
  while (!wd_cv_.wait_for(lock, std::chrono::duration<double>(opt_.watchdog_period_s),
                          [&] { return wd_stop_; })) {
    lock.unlock();
    if (opt_.heap_trim_s > 0 && std::chrono::steady_clock::now() - trimmed_at >
                                    std::chrono::duration<double>(opt_.heap_trim_s)) {
      heap_returned_ += return_free_heap();
      trimmed_at = std::chrono::steady_clock::now();
    }
    if (const int closed = close_idle_ingest_streams(*counters_, opt_.engine.stream_idle_s))
      log::info("ingest_streams_closed", "closed {} idle ingest stream{} (no request for {:.0f} s)",
                closed, closed > 1 ? "s" : "", opt_.engine.stream_idle_s);
    lock.lock();
    const Health h = engine_->health();
    if (h.serving != serving || h.store_ok != store_ok) {
      for (const std::string& r : h.reasons) log::error("not_serving", "NOT SERVING: {}", r);
      if (h.serving) log::info("serving", "serving again");
      set_health(h);
      serving = h.serving;
      store_ok = h.store_ok;
    }
    const auto now = std::chrono::steady_clock::now();
    if (h.serving) {
      unhealthy_since = std::chrono::steady_clock::time_point::min();
      continue;
    }
    if (unhealthy_since == std::chrono::steady_clock::time_point::min()) unhealthy_since = now;
    const double exit_after = opt_.engine.exit_after_s;
    if (exit_after > 0 && !fatal_called && opt_.on_fatal &&
        std::chrono::duration<double>(now - unhealthy_since).count() > exit_after) {
      fatal_called = true;
      lock.unlock();
      opt_.on_fatal(h);
      lock.lock();
    }
  }
}

void RangexServer::retention() {
  const RetentionSettings& r = plant_.retention;
  constexpr double kDayNs = 86400e9;
  std::unique_lock<std::mutex> lock(wd_mu_);
  do {
    PruneReport total;
    try {
      // In slices, the store free between them for the decisions still arriving.
      for (bool more = true; more && !wd_stop_;) {
        lock.unlock();
        const int64_t now = now_ns();
        const PruneReport p = store_->prune(now - int64_t(r.days * kDayNs),
                                            now - int64_t(r.images_days * kDayNs), 2000);
        lock.lock();
        total.links += p.links, total.fillets += p.fillets, total.images += p.images;
        total.audit_entries += p.audit_entries;
        more = p.more;
      }
    } catch (const std::exception& e) {
      if (!lock.owns_lock()) lock.lock();
      log::error("retention_failed", "retention pass failed (kept everything): {}", e.what());
    }
    if (total.links || total.images)
      log::info("retention_pruned",
                "pruned {} fillet records, {} audit entries and {} images (kept: records {:.0f} "
                "days, images {:.0f} days)",
                total.fillets, total.audit_entries, total.images, r.days, r.images_days);
  } while (!wd_cv_.wait_for(lock, std::chrono::duration<double>(r.every_h * 3600),
                            [&] { return wd_stop_; }));
}

bool RangexServer::shutdown(OpenFillets open) {
  if (down_) return true;
  down_ = true;
  {
    std::lock_guard<std::mutex> lock(wd_mu_);
    wd_stop_ = true;
  }
  wd_cv_.notify_all();
  if (watchdog_.joinable()) watchdog_.join();
  if (retention_.joinable()) retention_.join();
  Health stopping;
  stopping.serving = false;
  set_health(stopping);
  if (sensors_) sensors_->stop();  // the devices stop; what they made is drained below
  // Every accepted line decided and stored; lines arriving meanwhile are refused in-band.
  const bool drained = engine_->drain_and_stop(opt_.engine.drain_timeout_s, open);
  if (plc_) {
    plc_->flush(2);  // the last decisions to the PLC, then the lanes' stopped state
    plc_->stop();
  }
  hub_->close_all();  // subscribers get what is queued for them, then their streams end
  server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  store_->audit("rangexd", "server.stop", drained ? "drained" : "drain timed out");
  if (forwarder_) {
    // The last records on their way if the database is there; else they wait in the store
    // for the next start.
    forwarder_->wait_caught_up(2);
    engine_->set_forward_status(nullptr);
    forwarder_->stop();
  }
  return drained;
}

PlcStatus RangexServer::plc() const {
  return plc_ ? plc_->status() : PlcStatus{};
}

std::vector<PlcLaneView> RangexServer::plc_lanes() {
  std::vector<PlcLaneView> out;
  const bool store_ok = engine_->health().store_ok;
  for (const LaneState& l : engine_->lanes()) {
    PlcLaneView v;
    v.lane = l.config.id;
    v.has_count = l.fed;
    v.belt_count = l.last_encoder;
    bool blind = false;
    if (l.sensors)
      for (const SensorState& d : l.sensors->devices) blind = blind || d.state != "streaming";
    if (!store_ok)
      v.state = PackMl::kAborted, v.reason = StateReason::kStoreFailing;
    else if (blind)
      v.state = PackMl::kHeld, v.reason = StateReason::kSensorLost;
    else if (!l.fed || l.idle_ms > 5000)
      v.state = PackMl::kIdle, v.reason = StateReason::kNotFed;
    else
      v.state = PackMl::kExecute, v.reason = StateReason::kNone;
    out.push_back(v);
  }
  return out;
}

std::vector<LaneSensors> RangexServer::sensors() const {
  return sensors_ ? sensors_->state() : std::vector<LaneSensors>{};
}

void RangexServer::wait() {
  server_->Wait();
}

void RangexServer::continue_moved_lanes() {
  const std::string id = plant_.server_id.empty() ? host_name() : plant_.server_id;
  std::vector<int> lanes;
  for (const LaneConfig& l : plant_.lanes) lanes.push_back(l.id);
  std::vector<LaneHandover> moved;
  try {
    PgConnection db(plant_.results_db);
    require_plant_db_schema(db);
    moved = lane_handovers(db, id, lanes);
  } catch (const Error& e) {
    // Inspection does not wait for the database: a lane moved here while it is down numbers
    // its fillets from this store's records (its records still carry this server's id).
    log::warn("lane_history_unknown",
              "cannot read the lanes' history from PostgreSQL ({}); a lane moved here from "
              "another server numbers its fillets from this store",
              e.what());
    return;
  }
  for (const LaneHandover& h : moved) {
    opt_.engine.continue_lanes[h.lane] = {h.last_lane_fillet + 1, h.last_end};
    // In this server's chain: which link of which server the lane's history goes on from.
    store_->audit("rangexd", "lane.adopted", h.detail());
    log::info("lane_adopted", "{}", h.detail());
  }
}

void RangexServer::describe_for_fleet(const std::string& http_url,
                                      std::function<std::string()> health) {
  if (forwarder_) forwarder_->describe(http_url, std::move(health));
}

}  // namespace rangex
