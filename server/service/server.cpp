#include "service/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include <chrono>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "rangex/v1/rangex.grpc.pb.h"
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

// Runs a unary handler body, turning refused input into the status gRPC defines for it.
template <typename F>
Status guarded(F&& f) {
  try {
    return f();
  } catch (const NotFound& e) {
    return Status(StatusCode::NOT_FOUND, e.what());
  } catch (const AlreadyExists& e) {
    return Status(StatusCode::ALREADY_EXISTS, e.what());
  } catch (const FailedPrecondition& e) {
    return Status(StatusCode::FAILED_PRECONDITION, e.what());
  } catch (const Error& e) {
    return Status(StatusCode::INVALID_ARGUMENT, e.what());
  } catch (const std::exception& e) {
    return Status(StatusCode::INTERNAL, e.what());
  }
}

class IngestImpl final : public pb::IngestService::CallbackService {
 public:
  IngestImpl(Engine& e, StreamCounters& c) : engine_(e), counters_(c) {}
  grpc::ServerBidiReactor<pb::StreamLinesRequest, pb::StreamLinesResponse>* StreamLines(
      grpc::CallbackServerContext*) override {
    return new_ingest_stream(engine_, counters_);
  }

 private:
  Engine& engine_;
  StreamCounters& counters_;
};

class ResultsImpl final
    : public pb::ResultsService::WithCallbackMethod_SubscribeFillets<pb::ResultsService::Service> {
 public:
  ResultsImpl(Store& s, ResultsHub& h, StreamCounters& c) : store_(s), hub_(h), counters_(c) {}
  grpc::ServerWriteReactor<pb::SubscribeFilletsResponse>* SubscribeFillets(
      grpc::CallbackServerContext*, const pb::SubscribeFilletsRequest* req) override {
    return new_subscription(hub_, *req, counters_);
  }
  Status GetFillet(ServerContext*, const pb::GetFilletRequest* req,
                   pb::GetFilletResponse* resp) override {
    return guarded([&] {
      const auto f = store_.fillet(req->uid());
      if (!f) return Status(StatusCode::NOT_FOUND, "no fillet " + std::to_string(req->uid()));
      fill(resp->mutable_fillet(), *f);
      return Status::OK;
    });
  }
  Status ListFillets(ServerContext*, const pb::ListFilletsRequest* req,
                     pb::ListFilletsResponse* resp) override {
    return guarded([&] {
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
  Status GetFilletImage(ServerContext*, const pb::GetFilletImageRequest* req,
                        pb::GetFilletImageResponse* resp) override {
    return guarded([&] {
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
  Store& store_;
  ResultsHub& hub_;
  StreamCounters& counters_;
};

class CalibrationImpl final : public pb::CalibrationService::Service {
 public:
  CalibrationImpl(Engine& e, Store& s) : engine_(e), store_(s) {}
  Status UploadCalibration(ServerContext*, const pb::UploadCalibrationRequest* req,
                           pb::UploadCalibrationResponse* resp) override {
    return guarded([&] {
      fill(resp->mutable_calibration(),
           engine_.upload_calibration(req->lane(), req->id(), req->yaml(), req->who(),
                                      req->report_json()),
           false);
      return Status::OK;
    });
  }
  Status ListCalibrations(ServerContext*, const pb::ListCalibrationsRequest* req,
                          pb::ListCalibrationsResponse* resp) override {
    return guarded([&] {
      for (const auto& c : store_.calibrations(req->lane()))
        fill(resp->add_calibrations(), c, false);
      return Status::OK;
    });
  }
  Status GetCalibration(ServerContext*, const pb::GetCalibrationRequest* req,
                        pb::GetCalibrationResponse* resp) override {
    return guarded([&] {
      const auto c = store_.calibration(req->lane(), req->id());
      if (!c)
        return Status(StatusCode::NOT_FOUND, "lane " + std::to_string(req->lane()) +
                                                 " has no calibration '" + req->id() + "'");
      fill(resp->mutable_calibration(), *c, true);
      return Status::OK;
    });
  }
  Status ActivateCalibration(ServerContext*, const pb::ActivateCalibrationRequest* req,
                             pb::ActivateCalibrationResponse* resp) override {
    return guarded([&] {
      resp->set_pending(
          engine_.activate_calibration(req->lane(), req->id(), req->who(), req->force()));
      return Status::OK;
    });
  }

 private:
  Engine& engine_;
  Store& store_;
};

class ControlImpl final : public pb::ControlService::Service {
 public:
  ControlImpl(Engine& e, ResultsHub& h, StreamCounters& c, const ServerOptions& o, int64_t started)
      : engine_(e), hub_(h), counters_(c), opt_(o), started_(started) {}
  Status ListLanes(ServerContext*, const pb::ListLanesRequest*,
                   pb::ListLanesResponse* resp) override {
    return guarded([&] {
      for (const LaneState& l : engine_.lanes()) fill(resp->add_lanes(), l);
      return Status::OK;
    });
  }
  Status UpdateLaneThresholds(ServerContext*, const pb::UpdateLaneThresholdsRequest* req,
                              pb::UpdateLaneThresholdsResponse* resp) override {
    return guarded([&] {
      auto opt = [](bool has, double v) { return has ? std::optional<double>(v) : std::nullopt; };
      engine_.update_thresholds(req->lane(), opt(req->has_z_threshold(), req->z_threshold()),
                                opt(req->has_min_fragment_area_mm2(), req->min_fragment_area_mm2()),
                                opt(req->has_floor_mm(), req->floor_mm()), req->who());
      fill(resp->mutable_lane(), engine_.lane_state(req->lane()));
      return Status::OK;
    });
  }
  Status ResetLane(ServerContext*, const pb::ResetLaneRequest* req,
                   pb::ResetLaneResponse* resp) override {
    return guarded([&] {
      fill(resp->mutable_lane(), engine_.reset_lane(req->lane(), req->who(), req->reason()));
      return Status::OK;
    });
  }
  Status GetStatistics(ServerContext*, const pb::GetStatisticsRequest*,
                       pb::GetStatisticsResponse* resp) override {
    fill(resp, engine_.stats());
    resp->set_subscribers(hub_.subscribers());
    resp->set_ingest_streams(counters_.ingest);
    return Status::OK;
  }
  Status GetServerInfo(ServerContext*, const pb::GetServerInfoRequest*,
                       pb::GetServerInfoResponse* resp) override {
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
  }

 private:
  Engine& engine_;
  ResultsHub& hub_;
  StreamCounters& counters_;
  const ServerOptions& opt_;
  int64_t started_;
};

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
  started_ns_ = now_ns();
  store_ = std::make_unique<Store>(opt_.data_dir);
  hub_ = std::make_unique<ResultsHub>();
  engine_ = std::make_unique<Engine>(plant_, *store_, *hub_, opt_.engine);
  counters_ = std::make_unique<StreamCounters>();
  services_.reset(new Services{IngestImpl(*engine_, *counters_),
                               ResultsImpl(*store_, *hub_, *counters_),
                               CalibrationImpl(*engine_, *store_),
                               ControlImpl(*engine_, *hub_, *counters_, opt_, started_ns_)});
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder b;
  b.AddListeningPort(opt_.listen, grpc::InsecureServerCredentials(), &port_);
  b.SetMaxReceiveMessageSize(opt_.max_message_bytes);
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
  std::unique_lock<std::mutex> lock(wd_mu_);
  while (!wd_cv_.wait_for(lock, std::chrono::duration<double>(opt_.watchdog_period_s),
                          [&] { return wd_stop_; })) {
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

bool RangexServer::shutdown() {
  if (down_) return true;
  down_ = true;
  {
    std::lock_guard<std::mutex> lock(wd_mu_);
    wd_stop_ = true;
  }
  wd_cv_.notify_all();
  if (watchdog_.joinable()) watchdog_.join();
  Health stopping;
  stopping.serving = false;
  set_health(stopping);
  // Every accepted line decided and stored; lines arriving meanwhile are refused in-band.
  const bool drained = engine_->drain_and_stop(opt_.engine.drain_timeout_s);
  hub_->close_all();  // subscribers get what is queued for them, then their streams end
  server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  store_->audit("rangexd", "server.stop", drained ? "drained" : "drain timed out");
  return drained;
}

void RangexServer::wait() {
  server_->Wait();
}

}  // namespace rangex
