// rangexctl as a gRPC client of rangexd: feed, watch, status, fillets, image, calib
// upload|list|activate, lanes.
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>

#include "args.h"
#include "calib/lane_calibration_file.h"
#include "commands.h"
#include "core/error.h"
#include "feeder.h"
#include "line_source.h"
#include "rangex/v1/decision_names.h"
#include "rangex/v1/message_json.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "remote_call.h"
#include "sim/plant_simulator.h"
#include "watcher.h"

namespace rangex::cli {

namespace pb = rangex::v1;

int cmd_feed(int argc, char** argv) {
  const Args a(argc, argv, 2, {"simulate"},
               remote_options({"recording", "lanes", "fillets", "seed", "rate", "window",
                               "reconnect-for", "settle-for", "encoder-start"}));
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
  Feeder feeder(server_channel(a), fo);
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
  const Args a(argc, argv, 2, {},
               remote_options({"lane", "decision", "count", "seconds", "reconnect-for"}));
  WatchOptions wo;
  if (a.has("lane")) wo.filter.add_lanes(int(a.integer("lane", 0)));
  if (a.has("decision")) {
    const std::string d = a.get("decision", "");
    const pb::Decision value = decision_from_name(d);
    if (value == pb::DECISION_UNSPECIFIED)
      fail("--decision must be pass, reject or not_inspected (got '", d, "')");
    wo.filter.add_decisions(value);
  }
  const long count = a.integer("count", 0);
  if (count < 0) fail("--count must be >= 0 (got ", count, ")");
  wo.count = uint64_t(count);
  if (a.has("seconds"))
    wo.until = std::chrono::system_clock::now() + std::chrono::seconds(a.integer("seconds", 0));
  wo.reconnect_for_s = std::stod(a.get("reconnect-for", "60"));
  if (wo.reconnect_for_s < 0) fail("--reconnect-for must be >= 0");
  wo.show = [](const pb::FilletResult& f) {
    print_fillet(f);
    std::fflush(stdout);
  };
  wo.log = [](const std::string& m) { std::fprintf(stderr, "watch: %s\n", m.c_str()); };
  std::fprintf(stderr, "watch: %s, decisions from now on\n", server_address(a).c_str());
  const WatchReport r = Watcher(server_channel(a), wo).run();
  if (!r.status.ok()) check_status(r.status, "watch");
  return 0;
}

int cmd_status(int argc, char** argv) {
  const Args a(argc, argv, 2, {"json"}, remote_options({}));
  auto ch = server_channel(a);
  auto stub = pb::ControlService::NewStub(ch);
  UnaryCall c1, c2;
  pb::GetServerInfoResponse info;
  check_status(stub->GetServerInfo(&c1, {}, &info), "server info");
  pb::GetStatisticsResponse s;
  check_status(stub->GetStatistics(&c2, {}, &s), "statistics");
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
        p.address().c_str(),
        !p.connected()         ? "UNREACHABLE"
        : !p.refused().empty() ? "connected, REFUSING registers (the warning says which)"
                               : "connected",
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
  std::printf("fillets: %llu (%llu rejected, %llu not inspected); %d subscribers",
              (unsigned long long)s.fillets(), (unsigned long long)s.rejects(),
              (unsigned long long)s.not_inspected(), s.subscribers());
  if (s.subscribers_dropped())  // clients that stopped reading, ended for newer ones
    std::printf(" (%llu fell behind and gave way)", (unsigned long long)s.subscribers_dropped());
  std::printf("\n");
  if (s.open_files_limit())  // a server before the field says nothing
    std::printf("open files: %lld of %llu\n", (long long)s.open_files(),
                (unsigned long long)s.open_files_limit());
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
  const Args a(argc, argv, 2, {}, remote_options({"lane", "from-ns", "to-ns", "limit", "uid"}));
  auto stub = pb::ResultsService::NewStub(server_channel(a));
  if (a.has("uid")) {
    UnaryCall ctx;
    pb::GetFilletRequest req;
    req.set_uid(a.integer("uid", 0));
    pb::GetFilletResponse resp;
    check_status(stub->GetFillet(&ctx, req, &resp), "fillet");
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
    UnaryCall ctx;
    pb::ListFilletsResponse resp;
    check_status(stub->ListFillets(&ctx, req, &resp), "list fillets");
    for (const auto& f : resp.fillets())
      if (shown++ < limit) print_fillet(f);
    if (resp.next_page_token().empty()) break;
    req.set_page_token(resp.next_page_token());
  }
  return 0;
}

int cmd_image(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, remote_options({"uid", "kind", "out"}));
  auto stub = pb::ResultsService::NewStub(server_channel(a));
  UnaryCall ctx;
  pb::GetFilletImageRequest req;
  req.set_uid(std::stoll(a.require("uid")));
  req.set_kind(a.get("kind", "overlay"));
  pb::GetFilletImageResponse resp;
  check_status(stub->GetFilletImage(&ctx, req, &resp), "image");
  const std::string out = a.require("out");
  std::ofstream(out, std::ios::binary) << resp.png();
  std::printf("wrote %s (%zu bytes)\n", out.c_str(), resp.png().size());
  return 0;
}

int cmd_calib_remote(int argc, char** argv) {
  const std::string verb = argv[2];
  const Args a(argc, argv, 3, {"force"}, remote_options({"lane", "id", "file", "report"}));
  auto stub = pb::CalibrationService::NewStub(server_channel(a));
  UnaryCall ctx;
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
    check_status(stub->UploadCalibration(&ctx, req, &resp), "upload");
    std::printf("uploaded calibration '%s' for lane %d; report: %s\n",
                resp.calibration().id().c_str(), resp.calibration().lane(),
                resp.calibration().report_status().c_str());
  } else if (verb == "list") {
    pb::ListCalibrationsRequest req;
    req.set_lane(int(a.integer("lane", -1)));
    pb::ListCalibrationsResponse resp;
    check_status(stub->ListCalibrations(&ctx, req, &resp), "list");
    if (resp.calibrations().empty())
      std::printf("no calibrations uploaded%s: the lanes run on the plant configuration's\n",
                  req.lane() >= 0 ? (" for lane " + std::to_string(req.lane())).c_str() : "");
    for (const auto& c : resp.calibrations())
      std::printf("lane %d  %-24s %-7s report: %s\n", c.lane(), c.id().c_str(),
                  c.active() ? "active" : "", c.report_status().c_str());
  } else if (verb == "show") {
    pb::GetCalibrationRequest req;
    req.set_lane(int(a.integer("lane", 0)));
    req.set_id(a.require("id"));
    pb::GetCalibrationResponse resp;
    check_status(stub->GetCalibration(&ctx, req, &resp), "show");
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
    check_status(stub->ActivateCalibration(&ctx, req, &resp), "activate");
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

int cmd_lanes(int argc, char** argv) {
  const Args a(argc, argv, 2, {},
               remote_options({"lane", "z-threshold", "min-area-mm2", "floor-mm", "reason"}));
  auto stub = pb::ControlService::NewStub(server_channel(a));
  if (a.positional().size() == 1 && a.positional()[0] == "reset") {
    UnaryCall ctx;
    pb::ResetLaneRequest req;
    req.set_lane(int(std::stol(a.require("lane"))));
    req.set_reason(a.get("reason", ""));
    pb::ResetLaneResponse resp;
    check_status(stub->ResetLane(&ctx, req, &resp), "lane reset");
    std::printf("lane %d: its next line starts it afresh, whatever its encoder count\n",
                resp.lane().id());
    return 0;
  }
  if (a.positional().size() == 1 && a.positional()[0] == "set") {
    UnaryCall ctx;
    pb::UpdateLaneThresholdsRequest req;
    req.set_lane(int(std::stol(a.require("lane"))));
    if (a.has("z-threshold")) req.set_z_threshold(std::stod(a.get("z-threshold", "")));
    if (a.has("min-area-mm2")) req.set_min_fragment_area_mm2(std::stod(a.get("min-area-mm2", "")));
    if (a.has("floor-mm")) req.set_floor_mm(std::stod(a.get("floor-mm", "")));
    pb::UpdateLaneThresholdsResponse resp;
    check_status(stub->UpdateLaneThresholds(&ctx, req, &resp), "lane thresholds");
    std::printf("lane %d: z threshold %.2f, min fragment %.2f mm2, floor %.2f mm\n",
                resp.lane().id(), resp.lane().z_threshold(), resp.lane().min_fragment_area_mm2(),
                resp.lane().floor_mm());
    return 0;
  }
  a.expect_positionals(
      0,
      "lanes  |  lanes set --lane L [--z-threshold Z] [--min-area-mm2 A] [--floor-mm F]  |  "
      "lanes reset --lane L [--reason TEXT]");
  UnaryCall ctx;
  pb::ListLanesResponse resp;
  check_status(stub->ListLanes(&ctx, {}, &resp), "lanes");
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
