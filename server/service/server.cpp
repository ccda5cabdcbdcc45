#include "service/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include <chrono>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "service/access_control.h"
#include "service/heap_trim.h"
#include "service/pb_convert.h"
#include "service/streams.h"

namespace rangex {

namespace {

namespace pb = rangex::v1;
using grpc::ServerContext;
using grpc::Status;
using grpc::StatusCode;

constexpr const char* kServices[] = {"rangex.v1.IngestService", "rangex.v1.ResultsService",
                                     "rangex.v1.CalibrationService", "rangex.v1.ControlService"};

// The caller's identity from what its connection proved (throws Unauthenticated or
// PermissionDenied when it may not make the call `what`).
Identity caller(const AccessControl& access, const grpc::ServerContextBase& ctx, Role needed,
                const std::string& what) {
  std::string cn, authorization;
  if (const auto auth = ctx.auth_context(); auth && auth->IsPeerAuthenticated()) {
    const auto v = auth->FindPropertyValues("x509_common_name");
    if (!v.empty()) cn.assign(v[0].data(), v[0].size());
  }
  const auto& md = ctx.client_metadata();
  if (const auto it = md.find("authorization"); it != md.end())
    authorization.assign(it->second.data(), it->second.size());
  Identity who = access.identify(cn, authorization, ctx.peer());
  AccessControl::require(who, needed, what);
  return who;
}

// The status gRPC defines for a refused call or refused input.
Status refusal(const std::exception& e) {
  if (dynamic_cast<const Unauthenticated*>(&e))
    return Status(StatusCode::UNAUTHENTICATED, e.what());
  if (dynamic_cast<const PermissionDenied*>(&e))
    return Status(StatusCode::PERMISSION_DENIED, e.what());
  if (dynamic_cast<const NotFound*>(&e)) return Status(StatusCode::NOT_FOUND, e.what());
  if (dynamic_cast<const AlreadyExists*>(&e)) return Status(StatusCode::ALREADY_EXISTS, e.what());
  if (dynamic_cast<const FailedPrecondition*>(&e))
    return Status(StatusCode::FAILED_PRECONDITION, e.what());
  if (dynamic_cast<const Error*>(&e)) return Status(StatusCode::INVALID_ARGUMENT, e.what());
  return Status(StatusCode::INTERNAL, e.what());
}

// Runs a unary handler body for an authorised caller: every RPC names the role it needs.
template <typename F>
Status guarded(const AccessControl& access, const ServerContext* ctx, Role needed, const char* what,
               F&& f) {
  try {
    return f(caller(access, *ctx, needed, what));
  } catch (const std::exception& e) {
    return refusal(e);
  }
}

class IngestImpl final : public pb::IngestService::CallbackService {
 public:
  IngestImpl(const AccessControl& a, Engine& e, StreamCounters& c)
      : access_(a), engine_(e), counters_(c) {}
  grpc::ServerBidiReactor<pb::StreamLinesRequest, pb::StreamLinesResponse>* StreamLines(
      grpc::CallbackServerContext* ctx) override {
    try {
      caller(access_, *ctx, Role::operator_, "StreamLines");
    } catch (const std::exception& e) {
      return refused_ingest_stream(refusal(e));
    }
    return new_ingest_stream(engine_, counters_);
  }

 private:
  const AccessControl& access_;
  Engine& engine_;
  StreamCounters& counters_;
};

class ResultsImpl final
    : public pb::ResultsService::WithCallbackMethod_SubscribeFillets<pb::ResultsService::Service> {
 public:
  ResultsImpl(const AccessControl& a, Store& s, ResultsHub& h, StreamCounters& c)
      : access_(a), store_(s), hub_(h), counters_(c) {}
  grpc::ServerWriteReactor<pb::SubscribeFilletsResponse>* SubscribeFillets(
      grpc::CallbackServerContext* ctx, const pb::SubscribeFilletsRequest* req) override {
    try {
      caller(access_, *ctx, Role::viewer, "SubscribeFillets");
    } catch (const std::exception& e) {
      return refused_subscription(refusal(e));
    }
    return new_subscription(hub_, *req, counters_);
  }
  Status GetFillet(ServerContext* ctx, const pb::GetFilletRequest* req,
                   pb::GetFilletResponse* resp) override {
    return guarded(access_, ctx, Role::viewer, "GetFillet", [&](const Identity&) {
      const auto f = store_.fillet(req->uid());
      if (!f) return Status(StatusCode::NOT_FOUND, "no fillet " + std::to_string(req->uid()));
      fill(resp->mutable_fillet(), *f);
      return Status::OK;
    });
  }
  Status ListFillets(ServerContext* ctx, const pb::ListFilletsRequest* req,
                     pb::ListFilletsResponse* resp) override {
    return guarded(access_, ctx, Role::viewer, "ListFillets", [&](const Identity&) {
      int64_t after = 0;
      if (!req->page_token().empty()) {
        try {
          after = std::stoll(req->page_token());
        } catch (const std::exception&) {
          return Status(StatusCode::INVALID_ARGUMENT,
                        "malformed page token '" + req->page_token() + "'");
        }
      }
      const int size = req->page_size() <= 0 ? 100 : std::min(req->page_size(), 1000);
      const auto list =
          store_.list_fillets(req->from_ns(), req->to_ns(), req->lane(), after, size + 1);
      for (int i = 0; i < int(list.size()) && i < size; ++i) fill(resp->add_fillets(), list[i]);
      if (int(list.size()) > size) resp->set_next_page_token(std::to_string(list[size - 1].uid));
      return Status::OK;
    });
  }
  Status GetFilletImage(ServerContext* ctx, const pb::GetFilletImageRequest* req,
                        pb::GetFilletImageResponse* resp) override {
    return guarded(access_, ctx, Role::viewer, "GetFilletImage", [&](const Identity&) {
      const std::string kind = req->kind().empty() ? "overlay" : req->kind();
      const auto path = store_.image_path(req->uid(), kind);
      if (!path)
        return Status(StatusCode::NOT_FOUND,
                      "no " + kind + " image for fillet " + std::to_string(req->uid()) +
                          " (images are kept for rejected and not inspected fillets)");
      std::ifstream in(*path, std::ios::binary);
      std::stringstream ss;
      ss << in.rdbuf();
      resp->set_png(ss.str());
      return Status::OK;
    });
  }

 private:
  const AccessControl& access_;
  Store& store_;
  ResultsHub& hub_;
  StreamCounters& counters_;
};

class CalibrationImpl final : public pb::CalibrationService::Service {
 public:
  CalibrationImpl(const AccessControl& a, Engine& e, Store& s)
      : access_(a), engine_(e), store_(s) {}
  Status UploadCalibration(ServerContext* ctx, const pb::UploadCalibrationRequest* req,
                           pb::UploadCalibrationResponse* resp) override {
    return guarded(access_, ctx, Role::engineer, "UploadCalibration", [&](const Identity& who) {
      fill(resp->mutable_calibration(),
           engine_.upload_calibration(req->lane(), req->id(), req->yaml(), who.name,
                                      req->report_json()),
           false);
      return Status::OK;
    });
  }
  Status ListCalibrations(ServerContext* ctx, const pb::ListCalibrationsRequest* req,
                          pb::ListCalibrationsResponse* resp) override {
    return guarded(access_, ctx, Role::viewer, "ListCalibrations", [&](const Identity&) {
      for (const auto& c : store_.calibrations(req->lane()))
        fill(resp->add_calibrations(), c, false);
      return Status::OK;
    });
  }
  Status GetCalibration(ServerContext* ctx, const pb::GetCalibrationRequest* req,
                        pb::GetCalibrationResponse* resp) override {
    return guarded(access_, ctx, Role::viewer, "GetCalibration", [&](const Identity&) {
      const auto c = store_.calibration(req->lane(), req->id());
      if (!c)
        return Status(StatusCode::NOT_FOUND, "lane " + std::to_string(req->lane()) +
                                                 " has no calibration '" + req->id() + "'");
      fill(resp->mutable_calibration(), *c, true);
      return Status::OK;
    });
  }
  Status ActivateCalibration(ServerContext* ctx, const pb::ActivateCalibrationRequest* req,
                             pb::ActivateCalibrationResponse* resp) override {
    return guarded(access_, ctx, Role::engineer, "ActivateCalibration", [&](const Identity& who) {
      // Forcing overrides the calibration's quality gate: the server's own check.
      if (req->force()) AccessControl::require(who, Role::admin, "a forced ActivateCalibration");
      resp->set_pending(
          engine_.activate_calibration(req->lane(), req->id(), who.name, req->force()));
      return Status::OK;
    });
  }

 private:
  const AccessControl& access_;
  Engine& engine_;
  Store& store_;
};

class ControlImpl final : public pb::ControlService::Service {
 public:
  ControlImpl(const AccessControl& a, Engine& e, ResultsHub& h, StreamCounters& c,
              const ServerOptions& o, int64_t started)
      : access_(a), engine_(e), hub_(h), counters_(c), opt_(o), started_(started) {}
  Status ListLanes(ServerContext* ctx, const pb::ListLanesRequest*,
                   pb::ListLanesResponse* resp) override {
    return guarded(access_, ctx, Role::viewer, "ListLanes", [&](const Identity&) {
      for (const LaneState& l : engine_.lanes()) fill(resp->add_lanes(), l);
      return Status::OK;
    });
  }
  Status UpdateLaneThresholds(ServerContext* ctx, const pb::UpdateLaneThresholdsRequest* req,
                              pb::UpdateLaneThresholdsResponse* resp) override {
    return guarded(access_, ctx, Role::operator_, "UpdateLaneThresholds", [&](const Identity& who) {
      auto opt = [](bool has, double v) { return has ? std::optional<double>(v) : std::nullopt; };
      engine_.update_thresholds(req->lane(), opt(req->has_z_threshold(), req->z_threshold()),
                                opt(req->has_min_fragment_area_mm2(), req->min_fragment_area_mm2()),
                                opt(req->has_floor_mm(), req->floor_mm()), who.name);
      fill(resp->mutable_lane(), engine_.lane_state(req->lane()));
      return Status::OK;
    });
  }
  Status ResetLane(ServerContext* ctx, const pb::ResetLaneRequest* req,
                   pb::ResetLaneResponse* resp) override {
    return guarded(access_, ctx, Role::operator_, "ResetLane", [&](const Identity& who) {
      fill(resp->mutable_lane(), engine_.reset_lane(req->lane(), who.name, req->reason()));
      return Status::OK;
    });
  }
  Status UploadLearnedSettings(ServerContext* ctx, const pb::UploadLearnedSettingsRequest* req,
                               pb::UploadLearnedSettingsResponse* resp) override {
    return guarded(access_, ctx, Role::engineer, "UploadLearnedSettings", [&](const Identity& who) {
      fill(
          resp->mutable_settings(),
          engine_.upload_learned(req->lane(), req->id(), req->yaml(), req->report_json(), who.name),
          false);
      return Status::OK;
    });
  }
  Status ListLearnedSettings(ServerContext* ctx, const pb::ListLearnedSettingsRequest* req,
                             pb::ListLearnedSettingsResponse* resp) override {
    return guarded(access_, ctx, Role::viewer, "ListLearnedSettings", [&](const Identity&) {
      for (const auto& s : engine_.learned_settings(req->lane()))
        fill(resp->add_settings(), s, req->full());
      return Status::OK;
    });
  }
  Status ActivateLearnedSettings(ServerContext* ctx, const pb::ActivateLearnedSettingsRequest* req,
                                 pb::ActivateLearnedSettingsResponse* resp) override {
    return guarded(access_, ctx, Role::engineer, "ActivateLearnedSettings",
                   [&](const Identity& who) {
                     // Forcing overrides the learning's quality gate.
                     if (req->force())
                       AccessControl::require(who, Role::admin, "a forced ActivateLearnedSettings");
                     resp->set_pending(
                         engine_.activate_learned(req->lane(), req->id(), who.name, req->force()));
                     return Status::OK;
                   });
  }
  Status LearnProduct(ServerContext* ctx, const pb::LearnProductRequest* req,
                      pb::LearnProductResponse* resp) override {
    return guarded(access_, ctx, Role::engineer, "LearnProduct", [&](const Identity& who) {
      Engine::LearnRequest r;
      if (req->fillets() != 0) r.fillets = req->fillets();
      r.target_frr = req->target_frr();
      r.id = req->id();
      if (req->min_fillets() != 0) r.min_fillets = req->min_fillets();
      if (req->timeout_s() != 0) r.timeout_s = req->timeout_s();
      // The caller's deadline bounds the wait too.
      const auto left =
          std::chrono::duration<double>(ctx->deadline() - std::chrono::system_clock::now());
      if (left.count() > 0 && left.count() < r.timeout_s) r.timeout_s = left.count();
      fill(resp->mutable_settings(), engine_.learn_product(req->lane(), r, who.name), false);
      return Status::OK;
    });
  }
  Status GetStatistics(ServerContext* ctx, const pb::GetStatisticsRequest*,
                       pb::GetStatisticsResponse* resp) override {
    return guarded(access_, ctx, Role::viewer, "GetStatistics", [&](const Identity&) {
      fill(resp, engine_.stats());
      resp->set_subscribers(hub_.subscribers());
      resp->set_ingest_streams(counters_.ingest);
      return Status::OK;
    });
  }
  Status GetServerInfo(ServerContext* ctx, const pb::GetServerInfoRequest*,
                       pb::GetServerInfoResponse* resp) override {
    return guarded(access_, ctx, Role::viewer, "GetServerInfo", [&](const Identity&) {
      resp->set_version("rangex 0.1.0");
      resp->set_plant(engine_.plant().name);
      const BackendInfo b = engine_.backend();
      resp->set_backend(b.name);
      resp->set_device(b.device);
      resp->set_driver(b.driver);
      resp->set_limits(b.limits);
      resp->set_backend_note(engine_.backend_note());
      resp->set_storage(opt_.data_dir);
      resp->set_started_ns(started_);
      return Status::OK;
    });
  }

 private:
  const AccessControl& access_;
  Engine& engine_;
  ResultsHub& hub_;
  StreamCounters& counters_;
  const ServerOptions& opt_;
  int64_t started_;
};

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

struct RangexServer::Services {
  IngestImpl ingest;
  ResultsImpl results;
  CalibrationImpl calibration;
  ControlImpl control;
};

RangexServer::RangexServer(const PlantConfig& plant, ServerOptions opt)
    : plant_(plant), opt_(std::move(opt)) {
  if (opt_.listen.empty()) opt_.listen = plant_.listen;
  if (opt_.data_dir.empty()) opt_.data_dir = plant_.storage;
  check_listen_security(opt_.listen, plant_.security, "gRPC");
  if (opt_.heap_trim_s > 0) keep_large_blocks_out_of_arenas();
  started_ns_ = now_ns();
  store_ = std::make_unique<Store>(opt_.data_dir);
  hub_ = std::make_unique<ResultsHub>();
  engine_ = std::make_unique<Engine>(plant_, *store_, *hub_, opt_.engine);
  counters_ = std::make_unique<StreamCounters>();
  access_ = std::make_unique<AccessControl>(plant_.security);
  services_.reset(new Services{
      IngestImpl(*access_, *engine_, *counters_), ResultsImpl(*access_, *store_, *hub_, *counters_),
      CalibrationImpl(*access_, *engine_, *store_),
      ControlImpl(*access_, *engine_, *hub_, *counters_, opt_, started_ns_)});
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder b;
  b.AddListeningPort(opt_.listen, server_credentials(plant_.security), &port_);
  b.SetMaxReceiveMessageSize(opt_.max_message_bytes);
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
  b.RegisterService(&services_->ingest);
  b.RegisterService(&services_->results);
  b.RegisterService(&services_->calibration);
  b.RegisterService(&services_->control);
  server_ = b.BuildAndStart();
  if (!server_ || port_ == 0) {
    engine_->drain_and_stop();
    fail("cannot listen on ", opt_.listen);
  }
  set_health(engine_->health());
  store_->audit("rangexd", "server.start", "listening on " + address());
  watchdog_ = std::thread([this] { watchdog(); });
  retention_ = std::thread([this] { retention(); });
}

RangexServer::~RangexServer() {
  shutdown();
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
      std::fprintf(stderr, "rangexd: closed %d idle ingest stream%s (no request for %.0f s)\n",
                   closed, closed > 1 ? "s" : "", opt_.engine.stream_idle_s);
    lock.lock();
    const Health h = engine_->health();
    if (h.serving != serving || h.store_ok != store_ok) {
      for (const std::string& r : h.reasons)
        std::fprintf(stderr, "rangexd: NOT SERVING: %s\n", r.c_str());
      if (h.serving) std::fprintf(stderr, "rangexd: serving again\n");
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
      std::fprintf(stderr, "rangexd: retention pass failed (kept everything): %s\n", e.what());
    }
    if (total.links || total.images)
      std::fprintf(stderr,
                   "rangexd: retention: pruned %lld fillet records, %lld audit entries and "
                   "%lld images (kept: records %.0f days, images %.0f days)\n",
                   (long long)total.fillets, (long long)total.audit_entries,
                   (long long)total.images, r.days, r.images_days);
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
  // Every accepted line decided and stored; lines arriving meanwhile are refused in-band.
  const bool drained = engine_->drain_and_stop(opt_.engine.drain_timeout_s, open);
  hub_->close_all();  // subscribers get what is queued for them, then their streams end
  server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  store_->audit("rangexd", "server.stop", drained ? "drained" : "drain timed out");
  return drained;
}

void RangexServer::wait() {
  server_->Wait();
}

}  // namespace rangex
