#include "service/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include <chrono>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "rangex/v1/rangex.grpc.pb.h"

namespace rangex {

namespace {

namespace pb = rangex::v1;
using grpc::ServerContext;
using grpc::Status;
using grpc::StatusCode;

pb::Decision to_pb(const std::string& d) {
  if (d == "pass") return pb::DECISION_PASS;
  if (d == "reject") return pb::DECISION_REJECT;
  if (d == "not_inspected") return pb::DECISION_NOT_INSPECTED;
  return pb::DECISION_UNSPECIFIED;
}

std::string from_pb(pb::Decision d) {
  switch (d) {
    case pb::DECISION_PASS:
      return "pass";
    case pb::DECISION_REJECT:
      return "reject";
    case pb::DECISION_NOT_INSPECTED:
      return "not_inspected";
    default:
      return "";
  }
}

void fill(pb::FilletResult* o, const StoredFillet& f) {
  o->set_uid(f.uid);
  o->set_lane(f.lane);
  o->set_lane_fillet(f.lane_fillet);
  o->set_first_encoder(f.first_encoder);
  o->set_rows(f.rows);
  o->set_decision(to_pb(f.decision));
  o->set_reason(f.reason);
  o->set_beta0(f.beta0);
  o->set_beta1(f.beta1);
  o->set_residual_mean_dn(f.resid_mean_dn);
  o->set_residual_std_dn(f.resid_std_dn);
  o->set_calibration_id(f.calibration_id);
  o->set_decided_ns(f.decided_ns);
  o->set_belt_y0_mm(f.belt_y0_mm);
  for (const StoredFragment& g : f.fragments) {
    pb::Fragment* p = o->add_fragments();
    p->set_kind(g.kind);
    p->set_x_mm(g.x_mm);
    p->set_y_mm(g.y_mm);
    p->set_area_mm2(g.area_mm2);
    p->set_peak_z(g.peak_z);
    p->set_attenuation_mm2(g.attenuation_mm2);
  }
}

void fill(pb::CalibrationInfo* o, const StoredCalibration& c, bool with_yaml) {
  o->set_lane(c.lane);
  o->set_id(c.id);
  o->set_uploaded_ns(c.uploaded_ns);
  o->set_active(c.active);
  if (with_yaml) o->set_yaml(c.yaml);
}

void fill(pb::LaneInfo* o, const LaneConfig& l, const std::string& calibration) {
  o->set_id(l.id);
  o->set_frame_width(l.frame_width);
  o->set_frame_height(l.frame_height);
  o->set_xray_pixels(l.xray.pixels);
  o->set_encoder_step_mm(l.encoder_step_mm);
  o->set_calibration_id(calibration);
  o->set_z_threshold(l.inspection.z_threshold);
  o->set_min_fragment_area_mm2(l.inspection.min_fragment_area_mm2);
  o->set_floor_mm(l.inspection.floor_mm);
}

// Runs a unary handler body, turning refused input into INVALID_ARGUMENT with its message.
template <typename F>
Status guarded(F&& f) {
  try {
    return f();
  } catch (const Error& e) {
    return Status(StatusCode::INVALID_ARGUMENT, e.what());
  } catch (const std::exception& e) {
    return Status(StatusCode::INTERNAL, e.what());
  }
}

class IngestImpl final : public pb::IngestService::Service {
 public:
  explicit IngestImpl(Engine& e) : engine_(e) {}
  Status StreamLines(
      ServerContext*,
      grpc::ServerReaderWriter<pb::StreamLinesResponse, pb::StreamLinesRequest>* stream) override {
    pb::StreamLinesRequest req;
    while (stream->Read(&req)) {
      pb::StreamLinesResponse resp;
      resp.set_sequence(req.sequence());
      if (!req.has_line()) {
        resp.set_accepted(false);
        resp.mutable_error()->set_code("MISSING_LINE");
        resp.mutable_error()->set_message("request " + std::to_string(req.sequence()) +
                                          " carries no line");
      } else {
        pb::LineScan* l = req.mutable_line();
        IncomingLine in;
        in.lane = l->lane();
        in.encoder = l->encoder();
        in.cam0 = std::move(*l->mutable_cam0());
        in.cam1 = std::move(*l->mutable_cam1());
        in.xray = std::move(*l->mutable_xray());
        in.calibration_id = l->calibration_id();
        const Engine::Verdict v = engine_.submit(std::move(in));
        resp.set_accepted(v.accepted);
        resp.set_credit(v.credit);
        if (!v.accepted) {
          resp.mutable_error()->set_code(v.code);
          resp.mutable_error()->set_message(v.message);
        }
      }
      if (!stream->Write(resp)) break;  // the client went away; nothing of it is pending
    }
    return Status::OK;
  }

 private:
  Engine& engine_;
};

class ResultsImpl final : public pb::ResultsService::Service {
 public:
  ResultsImpl(Store& s, ResultsHub& h) : store_(s), hub_(h) {}
  Status SubscribeFillets(ServerContext* ctx, const pb::SubscribeFilletsRequest* req,
                          grpc::ServerWriter<pb::SubscribeFilletsResponse>* w) override {
    std::set<int> lanes(req->lanes().begin(), req->lanes().end());
    std::set<std::string> decisions;
    for (int d : req->decisions()) decisions.insert(from_pb(pb::Decision(d)));
    auto sub = hub_.subscribe(lanes, decisions);
    while (!ctx->IsCancelled()) {
      StoredFillet f;
      uint64_t lagged = 0;
      if (!hub_.next(sub, 200, f, lagged)) {
        if (sub->closed) break;
        continue;
      }
      pb::SubscribeFilletsResponse r;
      fill(r.mutable_fillet(), f);
      r.set_lagged(lagged);
      if (!w->Write(r)) break;
    }
    hub_.unsubscribe(sub);
    return Status::OK;
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
};

class CalibrationImpl final : public pb::CalibrationService::Service {
 public:
  CalibrationImpl(Engine& e, Store& s) : engine_(e), store_(s) {}
  Status UploadCalibration(ServerContext*, const pb::UploadCalibrationRequest* req,
                           pb::UploadCalibrationResponse* resp) override {
    return guarded([&] {
      fill(resp->mutable_calibration(),
           engine_.upload_calibration(req->lane(), req->id(), req->yaml(), req->who()), false);
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
      resp->set_pending(engine_.activate_calibration(req->lane(), req->id(), req->who()));
      return Status::OK;
    });
  }

 private:
  Engine& engine_;
  Store& store_;
};

class ControlImpl final : public pb::ControlService::Service {
 public:
  ControlImpl(Engine& e, ResultsHub& h, const ServerOptions& o, int64_t started)
      : engine_(e), hub_(h), opt_(o), started_(started) {}
  Status ListLanes(ServerContext*, const pb::ListLanesRequest*,
                   pb::ListLanesResponse* resp) override {
    return guarded([&] {
      for (const LaneConfig& l : engine_.lanes())
        fill(resp->add_lanes(), l, engine_.calibration_of(l.id));
      return Status::OK;
    });
  }
  Status UpdateLaneThresholds(ServerContext*, const pb::UpdateLaneThresholdsRequest* req,
                              pb::UpdateLaneThresholdsResponse* resp) override {
    return guarded([&] {
      auto opt = [](bool has, double v) { return has ? std::optional<double>(v) : std::nullopt; };
      const LaneConfig l = engine_.update_thresholds(
          req->lane(), opt(req->has_z_threshold(), req->z_threshold()),
          opt(req->has_min_fragment_area_mm2(), req->min_fragment_area_mm2()),
          opt(req->has_floor_mm(), req->floor_mm()), req->who());
      fill(resp->mutable_lane(), l, engine_.calibration_of(l.id));
      return Status::OK;
    });
  }
  Status GetStatistics(ServerContext*, const pb::GetStatisticsRequest*,
                       pb::GetStatisticsResponse* resp) override {
    const EngineStats s = engine_.stats();
    resp->set_lines_per_second(s.lines_per_second);
    resp->set_lines_received(s.received);
    resp->set_lines_processed(s.processed);
    for (const auto& [reason, n] : s.drops) {
      pb::DropCount* d = resp->add_drops();
      d->set_reason(reason);
      d->set_lines(n);
    }
    auto lat = [&](const char* stage, const LatencyStats::Summary& l) {
      pb::Latency* p = resp->add_latencies();
      p->set_stage(stage);
      p->set_p50_ms(l.p50);
      p->set_p99_ms(l.p99);
      p->set_samples(l.samples);
    };
    lat("queue_wait", s.queue_wait);
    lat("line_pipeline_batch", s.pipeline);
    lat("inspection_fillet", s.inspection);
    lat("last_line_to_decision", s.decision);
    resp->set_queue_depth(s.queue_depth);
    resp->set_queue_capacity(s.queue_capacity);
    resp->set_backend("cpu");
    resp->set_fillets(s.fillets);
    resp->set_rejects(s.rejects);
    resp->set_not_inspected(s.not_inspected);
    resp->set_subscribers(hub_.subscribers());
    return Status::OK;
  }
  Status GetServerInfo(ServerContext*, const pb::GetServerInfoRequest*,
                       pb::GetServerInfoResponse* resp) override {
    resp->set_version("rangex 0.1.0");
    resp->set_plant(engine_.plant().name);
    resp->set_backend("cpu");
    resp->set_storage(opt_.data_dir);
    resp->set_started_ns(started_);
    return Status::OK;
  }

 private:
  Engine& engine_;
  ResultsHub& hub_;
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
  services_.reset(new Services{IngestImpl(*engine_), ResultsImpl(*store_, *hub_),
                               CalibrationImpl(*engine_, *store_),
                               ControlImpl(*engine_, *hub_, opt_, started_ns_)});
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder b;
  b.AddListeningPort(opt_.listen, grpc::InsecureServerCredentials(), &port_);
  b.SetMaxReceiveMessageSize(opt_.max_message_bytes);
  b.RegisterService(&services_->ingest);
  b.RegisterService(&services_->results);
  b.RegisterService(&services_->calibration);
  b.RegisterService(&services_->control);
  server_ = b.BuildAndStart();
  if (!server_ || port_ == 0) fail("cannot listen on ", opt_.listen);
  store_->audit("rangexd", "server.start", "listening on " + address());
}

RangexServer::~RangexServer() {
  shutdown();
}

std::string RangexServer::address() const {
  const auto colon = opt_.listen.rfind(':');
  return opt_.listen.substr(0, colon) + ":" + std::to_string(port_);
}

void RangexServer::shutdown() {
  if (down_) return;
  down_ = true;
  engine_->drain_and_stop();  // every accepted line decided and stored
  hub_->close_all();
  server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  store_->audit("rangexd", "server.stop", "drained");
}

void RangexServer::wait() {
  server_->Wait();
}

}  // namespace rangex
