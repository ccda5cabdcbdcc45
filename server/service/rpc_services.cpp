#include "service/rpc_services.h"

#include <grpcpp/grpcpp.h>

#include <charconv>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/utf8.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "service/access_control.h"
#include "service/pb_convert.h"
#include "service/server.h"
#include "service/streams.h"

namespace rangex {

namespace {

namespace pb = rangex::v1;
using grpc::ServerContext;
using grpc::Status;
using grpc::StatusCode;

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
  if (dynamic_cast<const Unavailable*>(&e)) return Status(StatusCode::UNAVAILABLE, e.what());
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
  IngestImpl(const AccessControl& a, Engine& e, StreamCounters& c, IngestBound bound)
      : access_(a), engine_(e), counters_(c), bound_(bound) {}
  grpc::ServerBidiReactor<pb::StreamLinesRequest, pb::StreamLinesResponse>* StreamLines(
      grpc::CallbackServerContext* ctx) override {
    try {
      caller(access_, *ctx, Role::operator_, "StreamLines");
    } catch (const std::exception& e) {
      return refused_ingest_stream(refusal(e));
    }
    return new_ingest_stream(engine_, counters_, bound_);
  }

 private:
  const AccessControl& access_;
  Engine& engine_;
  StreamCounters& counters_;
  const IngestBound bound_;
};

class ResultsImpl final
    : public pb::ResultsService::WithCallbackMethod_SubscribeFillets<pb::ResultsService::Service> {
 public:
  ResultsImpl(const AccessControl& a, Store& s, ResultsHub& h, StreamCounters& c,
              int max_subscriptions)
      : access_(a), store_(s), hub_(h), counters_(c), max_subscriptions_(max_subscriptions) {}
  grpc::ServerWriteReactor<pb::SubscribeFilletsResponse>* SubscribeFillets(
      grpc::CallbackServerContext* ctx, const pb::SubscribeFilletsRequest* req) override {
    try {
      caller(access_, *ctx, Role::viewer, "SubscribeFillets");
    } catch (const std::exception& e) {
      return refused_subscription(refusal(e));
    }
    return new_subscription(hub_, *req, counters_, ctx, max_subscriptions_);
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
      // The token is the last uid a page held, given back whole ("12abc" is not 12).
      int64_t after = 0;
      const std::string& t = req->page_token();
      const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), after);
      if (!t.empty() && (ec != std::errc() || end != t.data() + t.size() || after < 0))
        return Status(StatusCode::INVALID_ARGUMENT,
                      "malformed page token '" + valid_utf8(t) + "' (give back next_page_token)");
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
  const int max_subscriptions_;
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
  Status StartRecording(ServerContext* ctx, const pb::StartRecordingRequest* req,
                        pb::StartRecordingResponse* resp) override {
    return guarded(access_, ctx, Role::operator_, "StartRecording", [&](const Identity& who) {
      RecordingRequest r;
      r.lanes.assign(req->lanes().begin(), req->lanes().end());
      r.minutes = req->minutes();
      r.name = req->name();
      fill(resp->mutable_recording(), engine_.start_recording(r, who.name));
      return Status::OK;
    });
  }
  Status StartVerification(ServerContext* ctx, const pb::StartVerificationRequest* req,
                           pb::StartVerificationResponse* resp) override {
    return guarded(access_, ctx, Role::operator_, "StartVerification", [&](const Identity& who) {
      VerificationRequest r;
      r.lane = req->lane();
      r.piece = req->piece();
      r.x_mm = req->x_mm();
      r.tolerance_mm = req->tolerance_mm();
      r.fillets = req->fillets();
      fill(resp->mutable_lane(), engine_.start_verification(r, who.name));
      return Status::OK;
    });
  }
  Status StopRecording(ServerContext* ctx, const pb::StopRecordingRequest*,
                       pb::StopRecordingResponse* resp) override {
    return guarded(access_, ctx, Role::operator_, "StopRecording", [&](const Identity& who) {
      fill(resp->mutable_recording(), engine_.stop_recording(who.name));
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
      r.min_fillets = req->min_fillets();
      if (req->timeout_s() != 0) r.timeout_s = req->timeout_s();
      r.tradeoff.assign(req->tradeoff_targets().begin(), req->tradeoff_targets().end());
      r.relearn_from = req->relearn_from();
      r.keep.assign(req->keep_fillets().begin(), req->keep_fillets().end());
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
      resp->set_subscribers_dropped(hub_.dropped());
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
      resp->set_now_ns(now_ns());
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

}  // namespace

struct RpcServices::Impl {
  IngestImpl ingest;
  ResultsImpl results;
  CalibrationImpl calibration;
  ControlImpl control;
};

RpcServices::RpcServices(const AccessControl& access, Engine& engine, Store& store, ResultsHub& hub,
                         StreamCounters& counters, const ServerOptions& opt, int64_t started_ns)
    : impl_(new Impl{IngestImpl(access, engine, counters,
                                {opt.engine.max_ingest_streams, opt.engine.stream_gives_way_s}),
                     ResultsImpl(access, store, hub, counters, opt.engine.max_subscriptions),
                     CalibrationImpl(access, engine, store),
                     ControlImpl(access, engine, hub, counters, opt, started_ns)}) {}

RpcServices::~RpcServices() = default;

void RpcServices::register_with(grpc::ServerBuilder& b) {
  b.RegisterService(&impl_->ingest);
  b.RegisterService(&impl_->results);
  b.RegisterService(&impl_->calibration);
  b.RegisterService(&impl_->control);
}

}  // namespace rangex
