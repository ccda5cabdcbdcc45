// rangexctl as a gRPC client of rangexd: feed, watch, status, fillets, image, calib
// upload|list|activate, lanes.
#include <grpcpp/grpcpp.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "args.h"
#include "calib/lane_calibration_file.h"
#include "commands.h"
#include "core/error.h"
#include "feeder.h"
#include "learn_report.h"
#include "line_source.h"
#include "rangex/v1/decision_names.h"
#include "rangex/v1/message_json.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "sim/plant_simulator.h"

namespace rangex::cli {

namespace {
namespace pb = rangex::v1;

// The options of every command that talks to rangexd, beside its own.
std::set<std::string> remote(std::set<std::string> own) {
  own.insert({"server", "config", "ca", "cert", "key", "token-file", "tls-name"});
  return own;
}

// TLS and credentials: the options, else RANGEX_CA, RANGEX_CERT, RANGEX_KEY and
// RANGEX_TOKEN or RANGEX_TOKEN_FILE (a token is never an argument: `ps` would show it).
ClientSecurity security(const Args& a) {
  ClientSecurity s = ClientSecurity::from_environment();
  s.ca = a.get("ca", s.ca);
  s.cert = a.get("cert", s.cert);
  s.key = a.get("key", s.key);
  s.server_name = a.get("tls-name", "");
  if (a.has("token-file"))
    s.token = ClientSecurity::read_token(a.get("token-file", ""), "--token-file");
  return s;
}

std::string server_address(const Args& a) {
  std::string addr = a.get("server", "");
  return addr.empty() ? load_config(a.get("config", "")).listen : addr;
}

std::shared_ptr<grpc::Channel> channel(const Args& a) {
  return rangex_channel(server_address(a), security(a));
}

// A unary call that cannot hang the command line: a server that does not answer in 15 s is
// reported as such.
struct Call : grpc::ClientContext {
  Call() { set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(15)); }
};

void check(const grpc::Status& s, const char* what) {
  if (s.ok()) return;
  // A plaintext client closed on by a TLS server sees only "Socket closed".
  const char* hint = s.error_code() == grpc::StatusCode::UNAVAILABLE
                         ? "; if rangexd speaks TLS, give its CA (--ca or RANGEX_CA)"
                         : "";
  fail(what, ": ", s.error_message().empty() ? "server unreachable" : s.error_message(), " (",
       int(s.error_code()), ")", hint);
}

// "NOT INSPECTED" for not_inspected; "?" for a value this build does not know.
std::string decision_text(pb::Decision d) {
  std::string t = decision_name(d);
  if (t.empty()) return "?";
  for (char& c : t) c = c == '_' ? ' ' : char(std::toupper(static_cast<unsigned char>(c)));
  return t;
}

void print_fillet(const pb::FilletResult& f) {
  std::printf("lane %d fillet %-5lld uid %-7lld %-13s", f.lane(), (long long)f.lane_fillet(),
              (long long)f.uid(), decision_text(f.decision()).c_str());
  if (!f.reason().empty()) std::printf(" %s", f.reason().c_str());
  for (const auto& g : f.fragments())
    if (g.kind() == "bone")
      std::printf("  [bone at x %.1f mm, belt %.1f mm, %.1f mm2, z %.1f]", g.x_mm(), g.y_mm(),
                  g.area_mm2(), g.peak_z());
  std::printf("\n");
}

}  // namespace

int cmd_feed(int argc, char** argv) {
  const Args a(argc, argv, 2, {"simulate"},
               remote({"recording", "lanes", "fillets", "seed", "rate", "window", "reconnect-for",
                       "settle-for", "encoder-start"}));
  a.expect_positionals(
      0,
      "feed (--recording DIR | --simulate [--lanes N] [--fillets M] [--seed S] [--encoder-start "
      "E]) [--rate LINES/S]");
  const PlantConfig plant = load_config(a.get("config", ""));
  std::unique_ptr<LineSource> src;
  if (a.has("recording")) {
    src = std::make_unique<RecordingSource>(a.get("recording", ""));
  } else if (a.flag("simulate")) {
    sim::SimulationParams p;
    p.lanes = int(a.integer("lanes", long(plant.lanes.size())));
    p.scene.fillets = int(a.integer("fillets", 5));
    p.seed = uint64_t(a.integer("seed", 1));
    // A later shift of the same lanes starts where the belt's count is now, not at 1000 again
    // (the server would take its lines for resends).
    p.encoder_start = a.integer("encoder-start", 1000);
    if (p.encoder_start < 0) fail("--encoder-start must be >= 0");
    if (p.lanes < 1 || p.lanes > int(plant.lanes.size()))
      fail("--lanes must be 1..", plant.lanes.size(), " (got ", p.lanes, ")");
    src = std::make_unique<SimulatedSource>(plant, p);
  } else {
    fail("feed needs --recording DIR or --simulate");
  }
  FeedOptions fo;
  fo.rate = std::stod(a.get("rate", "0"));  // per lane; 0: as fast as possible
  fo.window = int(a.integer("window", 256));
  fo.reconnect_for_s = std::stod(a.get("reconnect-for", "60"));
  fo.settle_for_s = std::stod(a.get("settle-for", "90"));
  if (fo.window < 1) fail("--window must be >= 1");
  fo.log = [](const std::string& m) { std::fprintf(stderr, "feed: %s\n", m.c_str()); };
  Feeder feeder(channel(a), fo);
  const FeedReport r = feeder.run(*src);
  std::printf(
      "fed %llu lines over %zu lanes in %.1f s (%.0f lines/s): %llu accepted, %llu refused\n",
      (unsigned long long)r.sent, src->lanes().size(), r.seconds, double(r.sent) / r.seconds,
      (unsigned long long)r.accepted, (unsigned long long)r.refused_total());
  if (r.reconnects)
    std::printf("  %llu reconnects, %llu lines resent (%llu the server already had)\n",
                (unsigned long long)r.reconnects, (unsigned long long)r.resent,
                (unsigned long long)r.duplicates);
  if (r.handed_back)
    std::printf(
        "  %llu refusals handed lines back (shutting down, store unavailable); sent "
        "again\n",
        (unsigned long long)r.handed_back);
  for (const auto& [code, n] : r.refused)
    std::printf("  %s: %llu\n", code.c_str(), (unsigned long long)n);
  if (r.settled && fo.settle_for_s > 0) std::printf("  every lane settled: all outcomes stored\n");
  for (const auto& [lane, span] : r.unsettled)
    std::printf(
        "  NOT SETTLED: lane %d counts %lld..%lld (their outcomes are not known to be "
        "stored)\n",
        lane, (long long)span.first, (long long)span.second);
  if (r.accepted + r.refused_total() < r.sent) {
    std::fflush(stdout);
    fail("feed: not every line was acknowledged (", r.status.error_message(), ")");
  }
  if (r.refused_total()) return 5;
  if (!r.settled) {
    std::fprintf(stderr, "feed: not every lane settled within --settle-for %.0f s%s%s\n",
                 fo.settle_for_s, r.status.ok() ? "" : ": ", r.status.error_message().c_str());
    return 6;
  }
  return 0;
}

int cmd_watch(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, remote({"lane", "decision", "count", "seconds"}));
  auto stub = pb::ResultsService::NewStub(channel(a));
  pb::SubscribeFilletsRequest req;
  if (a.has("lane")) req.add_lanes(int(a.integer("lane", 0)));
  if (a.has("decision")) {
    const std::string d = a.get("decision", "");
    const pb::Decision value = decision_from_name(d);
    if (value == pb::DECISION_UNSPECIFIED)
      fail("--decision must be pass, reject or not_inspected (got '", d, "')");
    req.add_decisions(value);
  }
  const long count = a.integer("count", 0);
  grpc::ClientContext ctx;
  if (a.has("seconds"))
    ctx.set_deadline(std::chrono::system_clock::now() +
                     std::chrono::seconds(a.integer("seconds", 0)));
  auto reader = stub->SubscribeFillets(&ctx, req);
  pb::SubscribeFilletsResponse r;
  long seen = 0;
  while (reader->Read(&r)) {
    if (r.lagged())
      std::printf("(this watcher was too slow: %llu results skipped)\n",
                  (unsigned long long)r.lagged());
    print_fillet(r.fillet());
    std::fflush(stdout);
    if (count && ++seen >= count) {
      ctx.TryCancel();
      break;
    }
  }
  const grpc::Status st = reader->Finish();
  if (!st.ok() && st.error_code() != grpc::StatusCode::DEADLINE_EXCEEDED &&
      st.error_code() != grpc::StatusCode::CANCELLED)
    check(st, "watch");
  return 0;
}

int cmd_status(int argc, char** argv) {
  const Args a(argc, argv, 2, {"json"}, remote({}));
  auto ch = channel(a);
  auto stub = pb::ControlService::NewStub(ch);
  Call c1, c2;
  pb::GetServerInfoResponse info;
  check(stub->GetServerInfo(&c1, {}, &info), "server info");
  pb::GetStatisticsResponse s;
  check(stub->GetStatistics(&c2, {}, &s), "statistics");
  if (a.flag("json")) {
    // GetStatistics as protobuf's JSON mapping (for scripts and dashboards' checks).
    std::printf("%s\n", to_json(s).c_str());
    return 0;
  }
  std::printf("%s, plant '%s', backend %s, store %s\n", info.version().c_str(),
              info.plant().c_str(), info.backend().c_str(), info.storage().c_str());
  std::printf("%s\n", s.serving() ? "SERVING" : "NOT SERVING");
  for (const auto& h : s.health()) std::printf("  %s\n", h.c_str());
  for (const auto& w : s.warnings()) std::printf("warning: %s\n", w.c_str());
  if (s.has_plc()) {
    const pb::PlcStatus& p = s.plc();
    std::printf(
        "PLC %s %s: %llu released, %llu diverted, %llu late, %llu unreleased, %llu "
        "waiting%s\n",
        p.address().c_str(), p.connected() ? "connected" : "UNREACHABLE",
        (unsigned long long)p.released(), (unsigned long long)p.diverted(),
        (unsigned long long)p.late(), (unsigned long long)p.unreleased(),
        (unsigned long long)p.pending(),
        p.least_spare_ms() >= 0
            ? (", least spare " + std::to_string(int(p.least_spare_ms())) + " ms").c_str()
            : "");
  }
  if (s.has_forwarding()) {
    const pb::ForwardingStatus& f = s.forwarding();
    std::printf(
        "forwarding as %s to PostgreSQL (%s): %s, %lld records (%.0f s) behind, link %lld of "
        "%lld%s%s\n",
        f.server_id().c_str(), f.database().c_str(), f.state().c_str(), (long long)f.lag_records(),
        f.lag_seconds(), (long long)f.forwarded_seq(), (long long)f.head_seq(),
        f.error().empty() ? "" : ": ", f.error().c_str());
  }
  std::printf(
      "lines: %llu received, %llu accepted, %llu processed, %.0f lines/s; queue %d of %d; %d "
      "ingest streams\n",
      (unsigned long long)s.lines_received(), (unsigned long long)s.lines_accepted(),
      (unsigned long long)s.lines_processed(), s.lines_per_second(), s.queue_depth(),
      s.queue_capacity(), s.ingest_streams());
  std::printf("fillets: %llu (%llu rejected, %llu not inspected); %d subscribers\n",
              (unsigned long long)s.fillets(), (unsigned long long)s.rejects(),
              (unsigned long long)s.not_inspected(), s.subscribers());
  for (const auto& d : s.refused())
    std::printf("refused %-22s %llu lines\n", d.reason().c_str(), (unsigned long long)d.lines());
  for (const auto& d : s.dropped())
    std::printf("dropped %-22s %llu lines\n", d.reason().c_str(), (unsigned long long)d.lines());
  if (s.lane_restarts() || s.store_errors())
    std::printf("lane restarts %llu, store errors %llu\n", (unsigned long long)s.lane_restarts(),
                (unsigned long long)s.store_errors());
  for (const auto& l : s.latencies())
    std::printf("latency %-22s p50 %8.2f ms  p99 %8.2f ms  (%llu)\n", l.stage().c_str(), l.p50_ms(),
                l.p99_ms(), (unsigned long long)l.samples());
  return 0;
}

int cmd_fillets(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, remote({"lane", "from-ns", "to-ns", "limit", "uid"}));
  auto stub = pb::ResultsService::NewStub(channel(a));
  if (a.has("uid")) {
    Call ctx;
    pb::GetFilletRequest req;
    req.set_uid(a.integer("uid", 0));
    pb::GetFilletResponse resp;
    check(stub->GetFillet(&ctx, req, &resp), "fillet");
    print_fillet(resp.fillet());
    std::printf("  b0 %.6f  b1 %.6f  residual %.2f +- %.2f DN  calibration %s  belt %.1f mm\n",
                resp.fillet().beta0(), resp.fillet().beta1(), resp.fillet().residual_mean_dn(),
                resp.fillet().residual_std_dn(), resp.fillet().calibration_id().c_str(),
                resp.fillet().belt_y0_mm());
    return 0;
  }
  const long limit = a.integer("limit", 50);
  pb::ListFilletsRequest req;
  req.set_lane(int(a.integer("lane", -1)));
  req.set_from_ns(a.integer("from-ns", 0));
  req.set_to_ns(a.integer("to-ns", 0));
  req.set_page_size(int(std::min(limit, 500L)));
  long shown = 0;
  while (shown < limit) {
    Call ctx;
    pb::ListFilletsResponse resp;
    check(stub->ListFillets(&ctx, req, &resp), "list fillets");
    for (const auto& f : resp.fillets())
      if (shown++ < limit) print_fillet(f);
    if (resp.next_page_token().empty()) break;
    req.set_page_token(resp.next_page_token());
  }
  return 0;
}

int cmd_image(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, remote({"uid", "kind", "out"}));
  auto stub = pb::ResultsService::NewStub(channel(a));
  Call ctx;
  pb::GetFilletImageRequest req;
  req.set_uid(std::stoll(a.require("uid")));
  req.set_kind(a.get("kind", "overlay"));
  pb::GetFilletImageResponse resp;
  check(stub->GetFilletImage(&ctx, req, &resp), "image");
  const std::string out = a.require("out");
  std::ofstream(out, std::ios::binary) << resp.png();
  std::printf("wrote %s (%zu bytes)\n", out.c_str(), resp.png().size());
  return 0;
}

int cmd_calib_remote(int argc, char** argv) {
  const std::string verb = argv[2];
  const Args a(argc, argv, 3, {"force"}, remote({"lane", "id", "file", "report"}));
  auto stub = pb::CalibrationService::NewStub(channel(a));
  Call ctx;
  if (verb == "upload") {
    std::ifstream in(a.require("file"));
    if (!in) fail(a.require("file"), ": cannot open");
    std::stringstream ss;
    ss << in.rdbuf();
    pb::UploadCalibrationRequest req;
    req.set_lane(int(a.integer("lane", 0)));
    req.set_id(a.require("id"));
    req.set_yaml(ss.str());
    // The solvers' reports: --report FILE, else those rangexctl calib wrote beside the file.
    std::string report;
    if (a.has("report")) {
      std::ifstream r(a.require("report"));
      if (!r) fail(a.require("report"), ": cannot open");
      std::stringstream rs;
      rs << r.rdbuf();
      report = rs.str();
    } else {
      report = lane_reports_json(a.require("file"));
    }
    req.set_report_json(report);
    pb::UploadCalibrationResponse resp;
    check(stub->UploadCalibration(&ctx, req, &resp), "upload");
    std::printf("uploaded calibration '%s' for lane %d; report: %s\n",
                resp.calibration().id().c_str(), resp.calibration().lane(),
                resp.calibration().report_status().c_str());
  } else if (verb == "list") {
    pb::ListCalibrationsRequest req;
    req.set_lane(int(a.integer("lane", -1)));
    pb::ListCalibrationsResponse resp;
    check(stub->ListCalibrations(&ctx, req, &resp), "list");
    for (const auto& c : resp.calibrations())
      std::printf("lane %d  %-24s %-7s report: %s\n", c.lane(), c.id().c_str(),
                  c.active() ? "active" : "", c.report_status().c_str());
  } else if (verb == "show") {
    pb::GetCalibrationRequest req;
    req.set_lane(int(a.integer("lane", 0)));
    req.set_id(a.require("id"));
    pb::GetCalibrationResponse resp;
    check(stub->GetCalibration(&ctx, req, &resp), "show");
    const auto& c = resp.calibration();
    std::printf("# lane %d calibration '%s'%s; report: %s\n%s", c.lane(), c.id().c_str(),
                c.active() ? " (active)" : "", c.report_status().c_str(), c.yaml().c_str());
    if (!c.report_json().empty()) std::printf("# report\n%s", c.report_json().c_str());
  } else if (verb == "activate") {
    pb::ActivateCalibrationRequest req;
    req.set_lane(int(a.integer("lane", 0)));
    req.set_id(a.require("id"));
    req.set_force(a.flag("force"));
    pb::ActivateCalibrationResponse resp;
    check(stub->ActivateCalibration(&ctx, req, &resp), "activate");
    std::printf(
        "calibration '%s' of lane %d activated; it takes over at the next batch without a fillet "
        "in progress\n",
        req.id().c_str(), req.lane());
  } else {
    fail("calib: unknown verb '", verb,
         "' (simulate, camera, staircase, xray, registration, validate, scatter, upload, list, "
         "show, activate)");
  }
  return 0;
}

namespace {

template <class... T>
void appendf(std::string& out, const char* fmt, T... v) {
  char b[1024];
  std::snprintf(b, sizeof b, fmt, v...);
  out += b;
}

std::string id_list(const google::protobuf::RepeatedField<int64_t>& list, const char* sep,
                    const std::string& prefix = "") {
  std::string out;
  for (int64_t f : list) out += (out.empty() ? "" : sep) + prefix + std::to_string(f);
  return out;
}

// A learned version as `learned list` shows it.
std::string learned_info_text(const pb::LearnedSettingsInfo& s) {
  std::string out;
  appendf(out, "lane %d  %-26s %-7s %4d fillets, target %.2f %%; report: %s\n", s.lane(),
          s.id().c_str(), s.active() ? "active" : "", s.fillets(), 100 * s.false_reject_target(),
          s.report_status().c_str());
  for (const auto& line : s.sensitivity()) appendf(out, "    %s\n", line.c_str());
  if (s.kept_fillets_size() > 0)
    appendf(out, "    kept in, checked clean: fillets %s\n",
            id_list(s.kept_fillets(), ", ").c_str());
  if (s.flagged_fillets_size() > 0)
    appendf(out, "    named as holding something like bone: fillets %s\n",
            id_list(s.flagged_fillets(), ", ").c_str());
  return out;
}

// One lane's live learning, start to end: what it stored and what to do next.
std::string learn_live(pb::ControlService::Stub& stub, const pb::LearnProductRequest& req,
                       long timeout_s, bool& passed) {
  grpc::ClientContext long_ctx;  // the fillets take as long as the line takes
  // Then the learning, and each other target's sensitivity (about 20 s for 40 fillets).
  const long learning_s = 120 + 60 * long(req.tradeoff_targets_size());
  long_ctx.set_deadline(std::chrono::system_clock::now() +
                        std::chrono::seconds(timeout_s + learning_s));
  pb::LearnProductResponse resp;
  check(stub.LearnProduct(&long_ctx, req, &resp), "learn");
  const pb::LearnedSettingsInfo& s = resp.settings();
  passed = s.report_status() == "passed";
  std::string out = learned_info_text(s);
  if (req.tradeoff_targets_size() > 0) {
    // What the other targets would buy, from the stored report.
    Call lctx;
    pb::ListLearnedSettingsRequest lreq;
    lreq.set_lane(s.lane());
    lreq.set_full(true);
    pb::ListLearnedSettingsResponse lresp;
    check(stub.ListLearnedSettings(&lctx, lreq, &lresp), "list");
    for (const auto& v : lresp.settings()) {
      if (v.id() != s.id()) continue;
      const auto report = nlohmann::json::parse(v.report_json(), nullptr, false);
      if (report.is_discarded() || !report.contains("tradeoff")) continue;
      out += "  what other false-reject targets would buy (the same fillets and pieces):\n";
      for (const auto& t : report["tradeoff"]) {
        appendf(out, "    %5.2f %% (implied %.3f %%):", 100 * t.value("target_frr", 0.0),
                100 * t.value("implied_frr", 0.0));
        for (const auto& line : t["summary"]) out.append(" ").append(line.get<std::string>());
        out += "\n";
      }
    }
  }
  if (s.report_status() == "passed")
    appendf(out,
            "stored as a new version, not active: rangexctl learned activate --lane %d --id %s\n",
            s.lane(), s.id().c_str());
  else
    out +=
        "stored as a new version; its learning failed, so its activation is refused unless "
        "forced (admin)\n";
  if (s.flagged_fillets_size() > 0)
    appendf(out,
            "if those fillets were checked and found clean, learn again from the same fillets "
            "keeping them:\n  rangexctl learned learn --lane %d --relearn-from %s --keep %s\n",
            s.lane(), s.id().c_str(),
            id_list(s.flagged_fillets(), ",", std::to_string(s.lane()) + ":").c_str());
  return out;
}

}  // namespace

// `rangexctl learned upload|list|activate|learn`: learned inspection settings on rangexd.
int cmd_learned(int argc, char** argv) {
  if (argc < 3) fail("usage: learned upload|list|activate|learn ...");
  const std::string verb = argv[2];
  const Args a(argc, argv, 3, {"force", "full"},
               remote({"lane", "lanes", "id", "file", "report", "fillets", "target-frr",
                       "min-fillets", "timeout", "tradeoff", "relearn-from", "keep"}));
  auto stub = pb::ControlService::NewStub(channel(a));
  Call ctx;
  auto show = [](const pb::LearnedSettingsInfo& s) {
    std::fputs(learned_info_text(s).c_str(), stdout);
  };
  if (verb == "upload") {
    // The lane's inspection.learned section of a plant configuration rangexctl learn wrote,
    // with the report it wrote beside it (--report, else PLANT.report/learn.json).
    const std::string file = a.require("file");
    const int lane = int(a.integer("lane", 0));
    YAML::Node root;
    try {
      root = YAML::LoadFile(file);
    } catch (const YAML::Exception& e) {
      fail(file, ": not valid YAML: ", e.what());
    }
    std::string section;
    for (const YAML::Node& ln : root["lanes"])
      if (ln["id"] && ln["id"].as<int>() == lane && ln["inspection"] &&
          ln["inspection"]["learned"]) {
        YAML::Emitter e;
        e << ln["inspection"]["learned"];
        section = e.c_str();
      }
    if (section.empty()) fail(file, ": lane ", lane, " has no inspection.learned section");
    const std::string report_file =
        a.get("report", (std::filesystem::path(file).parent_path() /
                         (std::filesystem::path(file).stem().string() + ".report") / "learn.json")
                            .string());
    std::string report;
    if (std::ifstream r(report_file); r) {
      std::stringstream rs;
      rs << r.rdbuf();
      report = rs.str();
    } else if (a.has("report")) {
      fail(report_file, ": cannot open");
    }
    pb::UploadLearnedSettingsRequest req;
    req.set_lane(lane);
    req.set_id(a.require("id"));
    req.set_yaml(section);
    req.set_report_json(report);
    pb::UploadLearnedSettingsResponse resp;
    check(stub->UploadLearnedSettings(&ctx, req, &resp), "upload");
    std::printf("uploaded learned settings '%s' for lane %d; report: %s\n",
                resp.settings().id().c_str(), resp.settings().lane(),
                resp.settings().report_status().c_str());
  } else if (verb == "list") {
    pb::ListLearnedSettingsRequest req;
    req.set_lane(int(a.integer("lane", -1)));
    req.set_full(a.flag("full"));
    pb::ListLearnedSettingsResponse resp;
    check(stub->ListLearnedSettings(&ctx, req, &resp), "list");
    for (const auto& s : resp.settings()) {
      show(s);
      if (a.flag("full")) std::printf("%s\n", s.yaml().c_str());
    }
  } else if (verb == "activate") {
    pb::ActivateLearnedSettingsRequest req;
    req.set_lane(int(a.integer("lane", 0)));
    req.set_id(a.require("id"));
    req.set_force(a.flag("force"));
    pb::ActivateLearnedSettingsResponse resp;
    check(stub->ActivateLearnedSettings(&ctx, req, &resp), "activate");
    std::printf(
        "learned settings '%s' of lane %d activated; they take over at the next batch without "
        "a fillet in progress\n",
        req.id().c_str(), req.lane());
  } else if (verb == "learn") {
    // --lanes 0,1,2: every lane listed learns its own product at once, from its own next
    // fillets (one call each).
    std::vector<int> lanes;
    if (a.has("lanes")) {
      if (a.has("lane")) fail("give --lane L or --lanes L,L,..., not both");
      for (int l : lane_list(a.get("lanes", ""))) {
        if (std::find(lanes.begin(), lanes.end(), l) != lanes.end())
          fail("--lanes: lane ", l, " is listed twice");
        lanes.push_back(l);
      }
      if (lanes.empty()) fail("--lanes must be lane ids separated by commas");
    } else {
      lanes.push_back(int(a.integer("lane", 0)));
    }
    pb::LearnProductRequest req;
    req.set_fillets(int(a.integer("fillets", 40)));
    req.set_min_fillets(int(a.integer("min-fillets", 0)));
    req.set_id(a.get("id", ""));
    if (a.has("target-frr")) req.set_target_frr(std::stod(a.get("target-frr", "0")));
    if (a.has("tradeoff"))
      for (double t : tradeoff_targets(a.get("tradeoff", ""))) req.add_tradeoff_targets(t);
    const long timeout = a.integer("timeout", 3600);
    if (timeout < 1 || timeout > 86400) fail("--timeout must be within 1..86400 s");
    req.set_timeout_s(double(timeout));
    // Again from the fillets of the lane's last live run, keeping the fillets it named that
    // an operator checked and found clean (--keep 0:7,0:12, as it names them).
    req.set_relearn_from(a.get("relearn-from", ""));
    if (a.has("keep")) {
      if (req.relearn_from().empty())
        fail(
            "--keep names fillets of an earlier learning run: give --relearn-from ID, the "
            "version that run stored");
      if (lanes.size() > 1) fail("--keep names one lane's fillets: give --lane L");
      for (const auto& [lane, id] : checked_clean_fillets(a.get("keep", ""))) {
        if (lane != lanes[0]) fail("--keep: fillet ", lane, ":", id, " is not of lane ", lanes[0]);
        req.add_keep_fillets(id);
      }
    }
    for (int l : lanes)
      if (req.relearn_from().empty())
        std::printf("lane %d: learning from its next %d fillets ...\n", l, req.fillets());
      else
        std::printf("lane %d: learning again from the fillets of '%s' ...\n", l,
                    req.relearn_from().c_str());
    std::fflush(stdout);
    // Each lane's outcome as it ends; a lane that fails does not stop the others.
    std::mutex out_mu;
    int failed = 0, failed_learning = 0;
    std::vector<std::thread> runs;
    for (int l : lanes)
      runs.emplace_back([&, l] {
        pb::LearnProductRequest mine = req;
        mine.set_lane(l);
        std::string text;
        bool ok = true, passed = false;
        try {
          text = learn_live(*stub, mine, timeout, passed);
        } catch (const std::exception& e) {
          text = "lane " + std::to_string(l) + ": " + e.what() + "\n";
          ok = false;
        }
        std::lock_guard<std::mutex> lock(out_mu);
        std::fputs(text.c_str(), ok ? stdout : stderr);
        std::fflush(ok ? stdout : stderr);
        failed += !ok;
        failed_learning += ok && !passed;
      });
    for (std::thread& t : runs) t.join();
    if (failed > 0) fail(failed, " of ", lanes.size(), " lanes learned nothing");
    // As `rangexctl learn`: a learning that failed (stored, but not to be activated) is 2.
    if (failed_learning > 0) {
      std::fprintf(stderr, "%d of %zu lanes' learning failed\n", failed_learning, lanes.size());
      return 2;
    }
  } else {
    fail("learned: unknown verb '", verb, "' (upload, list, activate, learn)");
  }
  return 0;
}

namespace {

void print_recording(const pb::RecordingStatus& r) {
  std::string lanes;
  for (int l : r.lanes()) lanes.append(lanes.empty() ? "" : ",").append(std::to_string(l));
  std::printf(
      "recording %s (lanes %s, %.1f minutes) %s: %llu lines, %llu MB of %llu MB, %llu "
      "left out%s%s\n  %s\n",
      r.name().c_str(), lanes.c_str(), r.minutes(), r.active() ? "running" : "ended",
      (unsigned long long)r.lines(), (unsigned long long)(r.bytes() >> 20),
      (unsigned long long)(r.budget_bytes() >> 20), (unsigned long long)r.left_out(),
      r.ended().empty() ? "" : "; ", r.ended().c_str(), r.dir().c_str());
}

}  // namespace

int cmd_record(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, remote({"lanes", "minutes", "name"}));
  a.expect_positionals(1,
                       "record start [--lanes 0,1] --minutes N [--name NAME]  |  record stop  "
                       "|  record status");
  const std::string verb = a.positional(0, "start|stop|status");
  auto stub = pb::ControlService::NewStub(channel(a));
  Call ctx;
  if (verb == "start") {
    pb::StartRecordingRequest req;
    // Lane ids from 0 (the server names one it does not have).
    const std::string list = a.get("lanes", "");
    for (size_t i = 0; i < list.size();) {
      const size_t j = std::min(list.find(',', i), list.size());
      const std::string item = list.substr(i, j - i);
      char* end = nullptr;
      const long n = std::strtol(item.c_str(), &end, 10);
      if (item.empty() || *end || n < 0 || n > 1000000)
        fail("--lanes takes lane ids separated by commas (got '", list, "')");
      req.add_lanes(int(n));
      i = j + 1;
    }
    req.set_minutes(std::stod(a.require("minutes")));
    req.set_name(a.get("name", ""));
    pb::StartRecordingResponse resp;
    check(stub->StartRecording(&ctx, req, &resp), "record start");
    print_recording(resp.recording());
    return 0;
  }
  if (verb == "stop") {
    pb::StopRecordingResponse resp;
    check(stub->StopRecording(&ctx, {}, &resp), "record stop");
    print_recording(resp.recording());
    std::printf("replay it: rangexctl process %s/laneL --out DIR\n",
                resp.recording().dir().c_str());
    return 0;
  }
  if (verb == "status") {
    pb::GetStatisticsResponse s;
    check(stub->GetStatistics(&ctx, {}, &s), "statistics");
    if (!s.has_recording()) {
      std::printf("no recording since the server started\n");
      return 0;
    }
    print_recording(s.recording());
    return 0;
  }
  fail("record takes start, stop or status (got '", verb, "')");
}

int cmd_verify(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, remote({"lane", "piece", "x-mm", "tolerance-mm", "fillets"}));
  a.expect_positionals(1,
                       "verify start --lane L --piece NAME --x-mm X [--tolerance-mm T] "
                       "[--fillets N]  |  verify list");
  const std::string verb = a.positional(0, "start|list");
  auto stub = pb::ControlService::NewStub(channel(a));
  Call ctx;
  if (verb == "start") {
    pb::StartVerificationRequest req;
    req.set_lane(int(std::stol(a.require("lane"))));
    req.set_piece(a.require("piece"));
    req.set_x_mm(std::stod(a.require("x-mm")));
    req.set_tolerance_mm(std::stod(a.get("tolerance-mm", "0")));
    req.set_fillets(int(std::stol(a.get("fillets", "0"))));
    pb::StartVerificationResponse resp;
    check(stub->StartVerification(&ctx, req, &resp), "verify start");
    std::printf("lane %d: verifying '%s': its next %d fillets must show it\n", resp.lane().id(),
                resp.lane().verification().running_piece().c_str(),
                resp.lane().verification().fillets_left());
    return 0;
  }
  if (verb != "list") fail("verify takes start or list (got '", verb, "')");
  pb::ListLanesResponse resp;
  check(stub->ListLanes(&ctx, {}, &resp), "lanes");
  for (const auto& l : resp.lanes()) {
    const pb::LaneVerification& v = l.verification();
    std::printf("lane %d: %s%s%s\n", l.id(),
                v.has_last() ? (v.passed() ? "passed: " : "FAILED: ") : "not verified yet",
                v.has_last() ? v.detail().c_str() : "",
                v.running() ? (" (running: " + v.running_piece() + ")").c_str()
                            : (v.overdue() ? " (due)" : ""));
  }
  return 0;
}

int cmd_lanes(int argc, char** argv) {
  const Args a(argc, argv, 2, {},
               remote({"lane", "z-threshold", "min-area-mm2", "floor-mm", "reason"}));
  auto stub = pb::ControlService::NewStub(channel(a));
  if (a.positional().size() == 1 && a.positional()[0] == "reset") {
    Call ctx;
    pb::ResetLaneRequest req;
    req.set_lane(int(std::stol(a.require("lane"))));
    req.set_reason(a.get("reason", ""));
    pb::ResetLaneResponse resp;
    check(stub->ResetLane(&ctx, req, &resp), "lane reset");
    std::printf("lane %d: its next line starts it afresh, whatever its encoder count\n",
                resp.lane().id());
    return 0;
  }
  if (a.positional().size() == 1 && a.positional()[0] == "set") {
    Call ctx;
    pb::UpdateLaneThresholdsRequest req;
    req.set_lane(int(std::stol(a.require("lane"))));
    if (a.has("z-threshold")) req.set_z_threshold(std::stod(a.get("z-threshold", "")));
    if (a.has("min-area-mm2")) req.set_min_fragment_area_mm2(std::stod(a.get("min-area-mm2", "")));
    if (a.has("floor-mm")) req.set_floor_mm(std::stod(a.get("floor-mm", "")));
    pb::UpdateLaneThresholdsResponse resp;
    check(stub->UpdateLaneThresholds(&ctx, req, &resp), "lane thresholds");
    std::printf("lane %d: z threshold %.2f, min fragment %.2f mm2, floor %.2f mm\n",
                resp.lane().id(), resp.lane().z_threshold(), resp.lane().min_fragment_area_mm2(),
                resp.lane().floor_mm());
    return 0;
  }
  a.expect_positionals(
      0,
      "lanes  |  lanes set --lane L [--z-threshold Z] [--min-area-mm2 A] [--floor-mm F]  |  "
      "lanes reset --lane L [--reason TEXT]");
  Call ctx;
  pb::ListLanesResponse resp;
  check(stub->ListLanes(&ctx, {}, &resp), "lanes");
  for (const auto& l : resp.lanes()) {
    std::printf(
        "lane %d: %dx%d frames, %d X-ray pixels, %.2f mm/line, calibration %s, z %.1f, min %.2f "
        "mm2, floor %.1f mm\n",
        l.id(), l.frame_width(), l.frame_height(), l.xray_pixels(), l.encoder_step_mm(),
        l.calibration_id().c_str(), l.z_threshold(), l.min_fragment_area_mm2(), l.floor_mm());
    if (l.fed())
      std::printf("        last encoder %lld, %llu lines, idle %.1f s%s, %llu restarts%s%s\n",
                  (long long)l.last_encoder(), (unsigned long long)l.lines_accepted(),
                  l.idle_ms() / 1e3, l.fillet_in_progress() ? ", fillet in progress" : "",
                  (unsigned long long)l.restarts(), l.last_restart().empty() ? "" : " (last: ",
                  l.last_restart().empty() ? "" : (l.last_restart() + ")").c_str());
    else
      std::printf("        not fed yet\n");
    if (!l.plc_state().empty()) std::printf("        PLC: %s\n", l.plc_state().c_str());
    if (l.has_sensors()) {
      const pb::LaneSensors& s = l.sensors();
      std::printf("        sensors (%s): %llu lines, %llu missing, %llu refused\n",
                  s.trigger().c_str(), (unsigned long long)s.lines(),
                  (unsigned long long)s.incomplete_lines(), (unsigned long long)s.refused_lines());
      for (const auto& d : s.devices())
        std::printf(
            "          %s %s %s: %llu frames, %llu incomplete, %llu lost, %llu "
            "reconnects%s%s\n",
            d.role().c_str(), d.device().c_str(), d.state().c_str(), (unsigned long long)d.frames(),
            (unsigned long long)d.incomplete(), (unsigned long long)d.lost_frames(),
            (unsigned long long)d.reconnects(), d.error().empty() ? "" : " - ", d.error().c_str());
    }
  }
  return 0;
}

}  // namespace rangex::cli
