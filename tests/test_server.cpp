// rangexd end to end on loopback: an in-process server, real gRPC clients.
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <map>
#include <set>
#include <thread>

#include "channel.h"
#include "core/plant_config.h"
#include "core/recording.h"
#include "grpc_raw.h"
#include "offline/replay.h"
#include "plc/plc_simulator.h"
#include "rangex/v1/decision_names.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "server_client.h"
#include "service/http_json.h"
#include "service/line_shape.h"
#include "service/metrics_text.h"
#include "service/pb_convert.h"
#include "service/plant_history.h"
#include "service/server.h"
#include "sim/plant_simulator.h"
#include "temp_dir.h"
#include "wait_until.h"

using namespace rangex;
using namespace rangex::test;
namespace pb = rangex::v1;

namespace {

PlantConfig plant() {
  return load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
}

ServerOptions options(const test::TempDir& t, size_t queue = 2048) {
  ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.data_dir = t.str("data");
  o.engine.queue_lines = queue;
  o.engine.backend = cpu_request(2);
  return o;
}

// Lines of one simulated lane, in memory (counts moved by `offset`).
struct Lines {
  std::vector<pb::LineScan> lines;
  Lines(const PlantConfig& p, int fillets, uint64_t seed, int lane = 0)
      : Lines(p, params(fillets, seed), lane) {}
  Lines(const PlantConfig& p, const sim::SimulationParams& sp, int lane, int64_t offset = 0) {
    const LaneConfig& lc = p.lane(lane);
    const sim::LaneSimulator sim(lc, sp);
    const size_t frame = size_t(lc.frame_width) * lc.frame_height;
    for (int64_t n = 0; n < sim.lines(); ++n) {
      pb::LineScan l;
      std::string c0(frame, '\0'), c1(frame, '\0'), x(size_t(lc.xray.pixels) * 2, '\0');
      sim.render(n, reinterpret_cast<uint8_t*>(c0.data()), reinterpret_cast<uint8_t*>(c1.data()),
                 reinterpret_cast<uint16_t*>(x.data()), nullptr, nullptr, nullptr);
      l.set_lane(lane);
      l.set_encoder(sim.encoder(n) + offset);
      l.set_cam0(std::move(c0));
      l.set_cam1(std::move(c1));
      l.set_xray(std::move(x));
      lines.push_back(std::move(l));
    }
  }
  static sim::SimulationParams params(int fillets, uint64_t seed) {
    sim::SimulationParams sp;
    sp.scene.fillets = fillets;
    sp.seed = seed;
    return sp;
  }
};

}  // namespace

TEST(Server, DecisionsEqualOfflineProcess) {
  test::TempDir t;
  const PlantConfig p = plant();
  sim::SimulationParams sp;
  sp.lanes = 1;
  sp.scene.fillets = 3;
  sp.seed = 2;
  sim::simulate_recording(p, sp, t.str("rec"));
  const RecordingReader rec(t.str("rec"));
  const auto offline = replay_recording(rec, p, {});
  ASSERT_EQ(offline.size(), 1u);
  ASSERT_GE(offline[0].fillets.size(), 3u);

  const std::vector<pb::LineScan> lines = recording_lines(rec, p);
  RangexServer server(p, options(t));
  const auto acks = stream(connect(server), lines);
  ASSERT_EQ(acks.size(), lines.size());
  for (const auto& a : acks) ASSERT_TRUE(a.accepted()) << a.error().message();
  server.shutdown();  // drains and closes the last fillet, as the offline replay does at its end
  const auto online = all_fillets(server.store());
  ASSERT_EQ(online.size(), offline[0].fillets.size());
  for (size_t i = 0; i < online.size(); ++i) {
    const FilletResult& o = offline[0].fillets[i].result;
    EXPECT_EQ(online[i].lane_fillet, o.id);
    EXPECT_EQ(online[i].decision, decision_name(o.decision)) << "fillet " << i;
    EXPECT_EQ(online[i].first_encoder, o.first_encoder);
    EXPECT_NEAR(online[i].beta1, o.fit.beta1, 1e-12);
    size_t bones = 0;
    for (const auto& f : online[i].fragments) bones += f.kind == "bone";
    EXPECT_EQ(bones, o.fragments.size());
  }
}

TEST(Server, BadInputGetsInBandErrorsAndTheStreamCarriesOn) {
  test::TempDir t;
  const PlantConfig p = plant();
  RangexServer server(p, options(t));
  const Lines good(p, 1, 5);
  auto bad = [&](std::function<void(pb::LineScan&)> f, int64_t enc) {
    pb::LineScan l = good.lines[0];
    l.set_encoder(enc);
    f(l);
    return l;
  };
  std::vector<pb::LineScan> seq = {
      good.lines[0],                                                           // ok
      bad([](pb::LineScan& l) { l.mutable_cam0()->resize(100); }, 1001),       // frame size
      bad([](pb::LineScan& l) { l.set_lane(9); }, 1001),                       // lane
      bad([](pb::LineScan&) {}, 999),                                          // backwards
      bad([](pb::LineScan&) {}, 1000),                                         // duplicate
      bad([](pb::LineScan& l) { l.mutable_cam1()->resize(10 << 20); }, 1001),  // oversized
      bad([](pb::LineScan& l) { l.mutable_xray()->resize(7); }, 1001),         // X-ray size
      bad([](pb::LineScan& l) { l.set_calibration_id("line-9-old"); }, 1001),  // calibration
      bad([](pb::LineScan& l) { *l.mutable_xray_high() = l.xray(); }, 1001),   // one energy
      good.lines[1],                                                           // ok again
  };
  const auto acks = stream(connect(server), seq);
  ASSERT_EQ(acks.size(), seq.size());
  const std::vector<std::string> codes = {"",
                                          "WRONG_FRAME_SIZE",
                                          "UNKNOWN_LANE",
                                          "ENCODER_BACKWARDS",
                                          "DUPLICATE_LINE",
                                          "OVERSIZED",
                                          "WRONG_XRAY_SIZE",
                                          "CALIBRATION_MISMATCH",
                                          "WRONG_XRAY_SIZE",
                                          ""};
  for (size_t i = 0; i < acks.size(); ++i) {
    EXPECT_EQ(acks[i].sequence(), i);
    EXPECT_EQ(acks[i].accepted(), codes[i].empty()) << i;
    EXPECT_EQ(acks[i].error().code(), codes[i]) << i << ": " << acks[i].error().message();
    if (!codes[i].empty()) EXPECT_FALSE(acks[i].error().message().empty());
    EXPECT_GT(acks[i].credit(), 0);
  }
  EXPECT_NE(acks[8].error().message().find("has one energy"), std::string::npos)
      << acks[8].error().message();
  const EngineStats s = server.engine().stats();
  EXPECT_EQ(s.refused.at("WRONG_FRAME_SIZE"), 1u);
  EXPECT_EQ(s.refused.at("DUPLICATE_LINE"), 1u);
}

// A dual-energy lane takes its high-energy line beside the low one, and refuses a line
// without it; the fillets it decides carry both X-ray lines into the store's images.
TEST(Server, ADualEnergyLaneTakesBothXrayLines) {
  test::TempDir t;
  PlantConfig p = plant();
  p.lanes.resize(1);
  p.lanes[0].xray.energies = 2;
  RangexServer server(p, options(t));
  const Lines good(p, 4, 3);
  std::vector<pb::LineScan> seq;
  for (const pb::LineScan& l : good.lines) {
    seq.push_back(l);
    // The high layer sees the harder beam: less attenuation, a brighter line.
    std::string hi = l.xray();
    auto* px = reinterpret_cast<uint16_t*>(hi.data());
    for (size_t i = 0; i < hi.size() / 2; ++i) px[i] = uint16_t(std::min(4095, px[i] + 200));
    *seq.back().mutable_xray_high() = hi;
  }
  pb::LineScan lacking = seq.back();
  lacking.set_encoder(lacking.encoder() + 1);
  lacking.clear_xray_high();
  seq.push_back(lacking);
  // A shift recorded meanwhile carries the high line too.
  const RecordingStatus started = server.engine().start_recording({{0}, 5, "dual"}, "test");
  const auto acks = stream(connect(server), seq);
  const RecordingStatus stopped = server.engine().stop_recording("test");
  ASSERT_EQ(acks.size(), seq.size());
  for (size_t i = 0; i + 1 < acks.size(); ++i) ASSERT_TRUE(acks[i].accepted()) << i;
  EXPECT_EQ(acks.back().error().code(), "WRONG_XRAY_SIZE");
  EXPECT_NE(acks.back().error().message().find("has two energies"), std::string::npos)
      << acks.back().error().message();
  server.shutdown();
  const auto fillets = server.store().list_fillets({});
  ASSERT_FALSE(fillets.empty());
  // Images are kept for the fillets not passed: each has both X-ray lines.
  int with_low = 0, with_high = 0;
  for (const StoredFillet& f : fillets) {
    const auto low = server.store().image_path(f.uid, "xray");
    const auto high = server.store().image_path(f.uid, "xray_high");
    with_low += low && std::filesystem::exists(*low);
    with_high += high && std::filesystem::exists(*high);
  }
  EXPECT_GT(with_low, 0);
  EXPECT_EQ(with_high, with_low);
  const RecordingReader recorded(started.dir + "/lane0");
  ASSERT_EQ(recorded.info().xray_energies, 2);
  // Every accepted line is in the recording or counted as left out: on a busy machine the
  // disk can fall behind the stream, and ingest never waits for it (shift_recorder.h).
  ASSERT_EQ(recorded.info().lines, int64_t(stopped.lines));
  EXPECT_EQ(stopped.lines + stopped.left_out, seq.size() - 1);
  ASSERT_GT(recorded.info().lines, 7);  // the queue holds 256 lines before any is left out
  std::vector<uint16_t> high(size_t(p.lanes[0].xray.pixels));
  recorded.read_high(0, 7, 1, high.data());
  EXPECT_EQ(0, std::memcmp(high.data(), seq[7].xray_high().data(), seq[7].xray_high().size()));
}

TEST(Server, ClientDisconnectMidStreamLeavesNothingBehind) {
  test::TempDir t;
  const PlantConfig p = plant();
  RangexServer server(p, options(t));
  const Lines lines(p, 1, 6);
  auto ch = connect(server);
  {
    auto stub = pb::IngestService::NewStub(ch);
    grpc::ClientContext ctx;
    auto s = stub->StreamLines(&ctx);
    for (int i = 0; i < 100; ++i) {
      pb::StreamLinesRequest req;
      req.set_sequence(i);
      *req.mutable_line() = lines.lines[i];
      s->Write(req);
    }
    pb::StreamLinesResponse r;
    int acked = 0;
    while (acked < 100 && s->Read(&r)) ++acked;
    ctx.TryCancel();  // gone without WritesDone
  }
  // Another client carries on from where the first stopped.
  const std::vector<pb::LineScan> rest(lines.lines.begin() + 100, lines.lines.end());
  const auto acks = stream(ch, rest);
  for (const auto& a : acks) ASSERT_TRUE(a.accepted()) << a.error().message();
  server.shutdown();
  const EngineStats s = server.engine().stats();
  EXPECT_EQ(s.processed, lines.lines.size());
  EXPECT_GE(s.fillets, 1u);
  for (const auto& f : all_fillets(server.store()))
    EXPECT_NE(f.decision, "not_inspected") << f.reason;
}

TEST(Server, OverloadDropsAreCountedAndFilletsFailSafe) {
  test::TempDir t;
  const PlantConfig p = plant();
  RangexServer server(p, options(t, 64));
  const Lines lines(p, 1, 7);
  auto ch = connect(server);
  // Feed in small chunks that the worker keeps up with, except for a stretch in the middle
  // of the fillet during which the worker stalls: the queue of 64 overflows there.
  const size_t mid = lines.lines.size() / 2, stall = 200;
  auto drained = [&] {
    while (server.engine().stats().queue_depth > 0)
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
  };
  auto chunked = [&](size_t from, size_t to) {
    for (size_t i = from; i < to; i += 32) {
      stream(ch, {lines.lines.begin() + long(i), lines.lines.begin() + long(std::min(to, i + 32))});
      drained();
    }
  };
  chunked(0, mid);
  server.engine().pause(true);
  const auto acks =
      stream(ch, {lines.lines.begin() + long(mid), lines.lines.begin() + long(mid + stall)});
  server.engine().pause(false);
  drained();
  chunked(mid + stall, lines.lines.size());
  size_t overload = 0;
  for (const auto& a : acks) overload += a.error().code() == "OVERLOAD";
  EXPECT_EQ(overload, stall - 64);
  server.shutdown();
  const EngineStats s = server.engine().stats();
  EXPECT_EQ(s.refused.at("OVERLOAD"), overload);
  EXPECT_EQ(s.processed, lines.lines.size() - overload);
  // The fillet whose lines were dropped is rejected as not inspected, never passed.
  const auto fillets = all_fillets(server.store());
  ASSERT_EQ(fillets.size(), 1u);
  EXPECT_EQ(fillets[0].decision, "not_inspected");
  EXPECT_NE(fillets[0].reason.find("lines missing"), std::string::npos) << fillets[0].reason;
}

TEST(Server, CalibrationActivatesBetweenFillets) {
  test::TempDir t;
  const PlantConfig p = plant();
  RangexServer server(p, options(t));
  auto ch = connect(server);
  auto cal = pb::CalibrationService::NewStub(ch);
  {  // malformed calibrations are refused, naming the key
    grpc::ClientContext c1, c2;
    pb::UploadCalibrationRequest bad;
    bad.set_lane(0);
    bad.set_id("broken");
    bad.set_yaml("cameras:\n  - intrinsics: {fx: .nan}\n  - {}\n");
    pb::UploadCalibrationResponse r;
    const grpc::Status s1 = cal->UploadCalibration(&c1, bad, &r);
    EXPECT_EQ(s1.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(s1.error_message().find("intrinsics.fx: must be finite"), std::string::npos)
        << s1.error_message();
    bad.set_yaml("laser_plane: {offset_mm: [1, 2]}\n");
    EXPECT_EQ(cal->UploadCalibration(&c2, bad, &r).error_code(),
              grpc::StatusCode::INVALID_ARGUMENT);
  }
  for (const int mib : {10, 50}) {
    // A calibration of 10 MB is refused by its size before it is parsed (a 50 MB one once
    // took minutes and 6.4 GB); one of 50 MB, past the largest message this plant's server
    // takes (16 MiB), by gRPC before it reaches the service. Each answer comes within the
    // deadline, and the server goes on.
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    pb::UploadCalibrationRequest huge;
    huge.set_lane(0);
    huge.set_id("huge");
    std::string yaml;
    while (yaml.size() < (size_t(mib) << 20)) yaml += "laser_plane: {normal: [0, 1, 0]}\n";
    huge.set_yaml(std::move(yaml));
    pb::UploadCalibrationResponse r;
    const grpc::Status s = cal->UploadCalibration(&c, huge, &r);
    if (mib == 10) {
      EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
      EXPECT_NE(s.error_message().find("calibration 'huge' is 10.0 MiB, more than the 1.0 MiB"),
                std::string::npos)
          << s.error_message();
    } else {
      EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
      EXPECT_NE(s.error_message().find("vs. 16777216"), std::string::npos) << s.error_message();
    }
  }
  {
    grpc::ClientContext c;
    pb::UploadCalibrationRequest up;
    up.set_lane(0);
    up.set_id("recal-2026-11-22");
    up.set_yaml("laser_plane: {normal: [0, 1, 0], offset_mm: 0.05}\n");
    up.set_who("test");
    pb::UploadCalibrationResponse r;
    ASSERT_TRUE(cal->UploadCalibration(&c, up, &r).ok());
  }
  const Lines lines(p, 4, 8);
  const size_t half = lines.lines.size() / 2;
  auto acks = stream(ch, {lines.lines.begin(), lines.lines.begin() + long(half)});
  // Acks mean queued, not processed: let the worker catch up, so that the first half is
  // measured with the first calibration whatever the machine's load.
  while (server.engine().stats().processed < half)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  {
    grpc::ClientContext c;
    pb::ActivateCalibrationRequest act;
    act.set_lane(0);
    act.set_id("recal-2026-11-22");
    act.set_who("test");
    act.set_force(true);  // a hand-written set without a solver report
    pb::ActivateCalibrationResponse r;
    ASSERT_TRUE(cal->ActivateCalibration(&c, act, &r).ok());
    EXPECT_TRUE(r.pending());
  }
  auto acks2 = stream(ch, {lines.lines.begin() + long(half), lines.lines.end()});
  for (const auto* list : {&acks, &acks2})
    for (const auto& a : *list) ASSERT_TRUE(a.accepted()) << a.error().message();
  server.shutdown();
  EXPECT_EQ(server.engine().stats().processed, lines.lines.size());  // no line lost
  const auto fillets = all_fillets(server.store());
  ASSERT_GE(fillets.size(), 4u);
  // Every fillet ran under one calibration; the switch happened once, between fillets.
  int switches = 0;
  for (size_t i = 1; i < fillets.size(); ++i)
    switches += fillets[i].calibration_id != fillets[i - 1].calibration_id;
  EXPECT_EQ(fillets.front().calibration_id, p.calibration_id);
  EXPECT_EQ(fillets.back().calibration_id, "recal-2026-11-22");
  EXPECT_EQ(switches, 1);
  const auto log = server.store().audit_log(20);
  bool audited = false;
  for (const auto& l : log)
    // The caller as the connection proved it (anonymous on loopback), never its own "who".
    audited |= l.find(
                   " calibration.activate.forced lane 0 id recal-2026-11-22: the "
                   "calibration has no report") != std::string::npos &&
               l.find(" anonymous@ipv4:127.0.0.1:") != std::string::npos &&
               l.find("test") == std::string::npos;
  EXPECT_TRUE(audited);
}

// Activation reads the solvers' report stored with the set: missing or failed refuses
// (FAILED_PRECONDITION, naming what failed) unless forced; an unreadable report is refused
// at upload; GetCalibration returns the report and its status.
TEST(Server, ActivationIsGatedByTheCalibrationReport) {
  test::TempDir t;
  const PlantConfig p = plant();
  RangexServer server(p, options(t));
  auto cal = pb::CalibrationService::NewStub(connect(server));
  const std::string yaml = "laser_plane: {normal: [0, 1, 0], offset_mm: 0.0}\n";
  const std::string passed =
      R"({"reports": [{"solver": "staircase", "subject": "lane 0 cam0", "passed": true,
          "parameters": [], "figures": {}, "warnings": [], "failures": []}]})";
  const std::string failed =
      R"({"reports": [{"solver": "xray", "subject": "lane 0 xray", "passed": false,
          "parameters": [], "figures": {}, "warnings": [],
          "failures": ["the fan-beam fit did not converge"]}]})";
  auto upload = [&](const std::string& id, const std::string& report) {
    grpc::ClientContext c;
    pb::UploadCalibrationRequest up;
    up.set_lane(0);
    up.set_id(id);
    up.set_yaml(yaml);
    up.set_who("integrator");
    up.set_report_json(report);
    pb::UploadCalibrationResponse r;
    return cal->UploadCalibration(&c, up, &r);
  };
  auto activate = [&](const std::string& id, bool force) {
    grpc::ClientContext c;
    pb::ActivateCalibrationRequest act;
    act.set_lane(0);
    act.set_id(id);
    act.set_who("integrator");
    act.set_force(force);
    pb::ActivateCalibrationResponse r;
    return cal->ActivateCalibration(&c, act, &r);
  };
  ASSERT_TRUE(upload("good", passed).ok());
  ASSERT_TRUE(upload("bad", failed).ok());
  ASSERT_TRUE(upload("none", "").ok());
  const grpc::Status garbled = upload("garbled", "{\"reports\": [");
  EXPECT_EQ(garbled.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(garbled.error_message().find("cannot be read"), std::string::npos)
      << garbled.error_message();

  const grpc::Status s_bad = activate("bad", false);
  EXPECT_EQ(s_bad.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s_bad.error_message().find("the fan-beam fit did not converge"), std::string::npos)
      << s_bad.error_message();
  const grpc::Status s_none = activate("none", false);
  EXPECT_EQ(s_none.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s_none.error_message().find("has no report"), std::string::npos)
      << s_none.error_message();
  EXPECT_TRUE(activate("good", false).ok());
  EXPECT_TRUE(activate("bad", true).ok());

  {
    grpc::ClientContext c;
    pb::GetCalibrationRequest g;
    g.set_lane(0);
    g.set_id("bad");
    pb::GetCalibrationResponse r;
    ASSERT_TRUE(cal->GetCalibration(&c, g, &r).ok());
    EXPECT_EQ(r.calibration().report_json(), failed);
    EXPECT_NE(r.calibration().report_status().find("xray solve of lane 0 xray failed"),
              std::string::npos)
        << r.calibration().report_status();
    EXPECT_TRUE(r.calibration().active());
  }
  bool plain = false, forced = false;
  for (const auto& l : server.store().audit_log(20)) {
    // The name the client claimed is not recorded: the audit names the caller as proved.
    EXPECT_EQ(l.find("integrator"), std::string::npos) << l;
    const bool caller = l.find(" anonymous@ipv4:127.0.0.1:") != std::string::npos;
    plain |= caller && l.find(" calibration.activate lane 0 id good") != std::string::npos;
    forced |= caller && l.find(" calibration.activate.forced lane 0 id bad: the xray solve") !=
                            std::string::npos;
  }
  EXPECT_TRUE(plain);
  EXPECT_TRUE(forced);
}

// A shift recorded on the server replays, with rangexctl process's replay, to the decisions
// the server made; one that would not fit the disk is refused before it starts.
TEST(Server, AShiftRecordedOnTheServerReplaysToItsDecisions) {
  test::TempDir t;
  const PlantConfig p = plant();
  const Lines lane0(p, 2, 3, 0);
  RangexServer server(p, options(t));
  auto control = pb::ControlService::NewStub(connect(server));
  {
    grpc::ClientContext ctx;
    pb::StartRecordingRequest req;
    req.add_lanes(0);
    req.set_minutes(5);
    req.set_name("shift-a");
    pb::StartRecordingResponse resp;
    ASSERT_TRUE(control->StartRecording(&ctx, req, &resp).ok());
    EXPECT_TRUE(resp.recording().active());
    grpc::ClientContext again;
    const grpc::Status twice = control->StartRecording(&again, req, &resp);
    EXPECT_EQ(twice.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << twice.error_message();
  }
  // Fed in parts no larger than the recorder's queue, each once the recorder has written the
  // last: ingest never waits for the disk, so a feeder faster than a busy machine's disk
  // leaves lines out of a recording (counted, below), and this test is about the replay.
  const size_t part = 128;
  for (size_t from = 0; from < lane0.lines.size(); from += part) {
    const std::vector<pb::LineScan> some(
        lane0.lines.begin() + std::ptrdiff_t(from),
        lane0.lines.begin() + std::ptrdiff_t(std::min(lane0.lines.size(), from + part)));
    for (const auto& a : stream(connect(server), some))
      ASSERT_TRUE(a.accepted()) << a.error().message();
    const uint64_t sent = from + some.size();
    ASSERT_TRUE(wait_until(120,
                           [&] {
                             grpc::ClientContext ctx;
                             pb::GetStatisticsResponse st;
                             return control->GetStatistics(&ctx, {}, &st).ok() &&
                                    st.recording().lines() + st.recording().left_out() >= sent;
                           }))
        << "the recorder did not take " << sent << " lines within 120 s";
  }
  pb::RecordingStatus rec;
  {
    grpc::ClientContext ctx;
    pb::StopRecordingResponse resp;
    ASSERT_TRUE(control->StopRecording(&ctx, {}, &resp).ok());
    rec = resp.recording();
  }
  EXPECT_FALSE(rec.active());
  EXPECT_EQ(rec.lines(), lane0.lines.size());
  EXPECT_EQ(rec.left_out(), 0u);
  {
    // A day of every lane at the rate just seen does not fit this disk: refused, naming why.
    grpc::ClientContext ctx;
    pb::StartRecordingRequest req;
    req.set_minutes(1440);
    pb::StartRecordingResponse resp;
    const grpc::Status st = control->StartRecording(&ctx, req, &resp);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << st.error_message();
    EXPECT_NE(st.error_message().find("MB free"), std::string::npos) << st.error_message();
  }
  server.shutdown();
  const RecordingReader recorded(rec.dir() + "/lane0");
  EXPECT_EQ(recorded.info().lines, int64_t(lane0.lines.size()));
  const auto offline = replay_recording(recorded, p, {});
  const auto online = all_fillets(server.store());
  ASSERT_EQ(online.size(), offline[0].fillets.size());
  ASSERT_GE(online.size(), 2u);
  for (size_t i = 0; i < online.size(); ++i) {
    EXPECT_EQ(online[i].decision, decision_name(offline[0].fillets[i].result.decision));
    EXPECT_EQ(online[i].first_encoder, offline[0].fillets[i].result.first_encoder);
  }
  int audited = 0;
  for (const AuditEntry& e : server.store().audit_entries(1000))
    audited += e.what == "recording.start" || e.what == "recording.end";
  EXPECT_EQ(audited, 2);
}

// A verification run: the lane's next fillets or test cards must show the declared piece
// where it was placed. Simulated test cards carry a 2 mm calcified sphere 20 mm off the
// lane's centre: declared there it passes; declared 60 mm away it fails after the cards
// allowed. Both audited, and the last result read back at restart.
TEST(Server, AVerificationPassesWhereThePieceIsAndFailsWhereItIsNot) {
  test::TempDir t;
  const PlantConfig p = plant();
  sim::SimulationParams sp;
  sp.scene.fillets = 3;
  sp.seed = 9;
  sp.scene.test_cards = sim::TestCard{};
  sp.scene.test_cards->piece_x_mm = 20;
  auto first = std::make_unique<RangexServer>(p, options(t));
  RangexServer& server = *first;
  auto control = pb::ControlService::NewStub(connect(server));
  auto verify = [&](double at, int fillets) {
    grpc::ClientContext ctx;
    pb::StartVerificationRequest req;
    req.set_lane(0);
    req.set_piece("2 mm calcified sphere");
    req.set_x_mm(at);
    req.set_tolerance_mm(10);
    req.set_fillets(fillets);
    pb::StartVerificationResponse resp;
    return control->StartVerification(&ctx, req, &resp);
  };
  ASSERT_TRUE(verify(20, 3).ok());
  EXPECT_EQ(verify(20, 3).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  stream(connect(server), Lines(p, sp, 0).lines);
  ASSERT_TRUE(test::wait_until(
      30, [&] { return server.engine().lane_state(0).verification.last.has_value(); }));
  LaneVerification v = server.engine().lane_state(0).verification;
  EXPECT_TRUE(v.last->passed) << v.last->detail;
  EXPECT_GT(v.last->fillet_uid, 0);
  EXPECT_NEAR(v.last->found_x_mm, 20, 10);
  EXPECT_FALSE(v.overdue);
  ASSERT_TRUE(verify(-40, 3).ok());
  stream(connect(server), Lines(p, sp, 0, 100000).lines);
  server.shutdown();
  v = server.engine().lane_state(0).verification;
  ASSERT_TRUE(v.last);
  EXPECT_FALSE(v.last->passed) << v.last->detail;
  EXPECT_TRUE(v.overdue);  // a failed verification makes the lane due
  std::vector<std::string> audited;
  for (const AuditEntry& e : server.store().audit_entries(1000))
    if (e.what.rfind("verification.", 0) == 0) audited.push_back(e.what);
  EXPECT_EQ(audited, (std::vector<std::string>{"verification.start", "verification.pass",
                                               "verification.start", "verification.fail"}));
  // A restarted server knows the lane's last result (one store to a directory: the first
  // lets go of it).
  first.reset();
  RangexServer restarted(p, options(t));
  const LaneVerification back = restarted.engine().lane_state(0).verification;
  ASSERT_TRUE(back.last);
  EXPECT_FALSE(back.last->passed);
  EXPECT_EQ(back.last->piece, "2 mm calcified sphere");
}

TEST(Server, RestartKeepsResultsAndCalibrations) {
  test::TempDir t;
  const PlantConfig p = plant();
  const Lines lines(p, 2, 9);
  size_t stored = 0;
  {
    RangexServer server(p, options(t));
    server.engine().upload_calibration(0, "cal-b", "laser_plane: {offset_mm: 0.0}\n", "test");
    server.engine().activate_calibration(0, "cal-b", "test", true);
    stream(connect(server), lines.lines);
    server.shutdown();
    stored = all_fillets(server.store()).size();
    ASSERT_GE(stored, 2u);
  }
  RangexServer again(p, options(t));
  EXPECT_EQ(all_fillets(again.store()).size(), stored);
  EXPECT_EQ(again.engine().calibration_of(0), "cal-b");
  auto results = pb::ResultsService::NewStub(connect(again));
  grpc::ClientContext c;
  pb::ListFilletsRequest req;
  req.set_lane(-1);
  req.set_page_size(1);
  pb::ListFilletsResponse resp;
  ASSERT_TRUE(results->ListFillets(&c, req, &resp).ok());
  EXPECT_EQ(resp.fillets_size(), 1);
  EXPECT_FALSE(resp.next_page_token().empty());
}

// gRPC's default SO_REUSEPORT let a second rangexd start on the first's address and take
// some of its clients.
TEST(Server, AnAddressAnotherServerListensOnIsRefusedNotShared) {
  test::TempDir t, u;
  RangexServer first(plant(), options(t));
  ServerOptions o = options(u);
  o.listen = first.address();
  try {
    RangexServer second(plant(), o);
    ADD_FAILURE() << "a second rangexd listens on " << o.listen;
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("cannot listen on " + o.listen), std::string::npos)
        << e.what();
  }
  auto control = pb::ControlService::NewStub(connect(first));
  grpc::ClientContext c;
  pb::GetServerInfoResponse info;
  EXPECT_TRUE(control->GetServerInfo(&c, pb::GetServerInfoRequest(), &info).ok());
}

// A page token is the last uid a page held, given back whole: "2abc" was read as 2.
TEST(Server, AMalformedPageTokenIsRefusedNamingIt) {
  test::TempDir t;
  RangexServer server(plant(), options(t));
  auto results = pb::ResultsService::NewStub(connect(server));
  auto list = [&](const std::string& token) {
    grpc::ClientContext c;
    pb::ListFilletsRequest req;
    req.set_lane(-1);
    req.set_page_token(token);
    pb::ListFilletsResponse resp;
    return results->ListFillets(&c, req, &resp);
  };
  for (const std::string token : {"2abc", "-1", "99999999999999999999", " 2", "0x10"}) {
    const grpc::Status s = list(token);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << token;
    EXPECT_NE(s.error_message().find("malformed page token '" + token + "'"), std::string::npos)
        << s.error_message();
  }
  EXPECT_TRUE(list("2").ok());
  EXPECT_TRUE(list("").ok());
}

TEST(Server, RestartContinuesFilletNumbersAndIdleCountsLinesReceived) {
  test::TempDir t;
  const PlantConfig p = plant();
  Lines lines(p, 2, 9);
  std::set<int64_t> before;
  {
    RangexServer server(p, options(t));
    stream(connect(server), lines.lines);
    server.shutdown();
    for (const auto& f : all_fillets(server.store())) before.insert(f.lane_fillet);
    ASSERT_GE(before.size(), 2u);
  }
  RangexServer again(p, options(t));
  auto ch = connect(again);
  // The feeder resends what it had: the first half, long durable, is all duplicates, yet the
  // lane is being fed (idle counted from lines received: once "no line for 662 s" 90 s after
  // the last line).
  const std::vector<pb::LineScan> first_half(lines.lines.begin(),
                                             lines.lines.begin() + long(lines.lines.size() / 2));
  for (const auto& a : stream(ch, first_half)) EXPECT_EQ(a.error().code(), "DUPLICATE_LINE");
  const LaneState s = again.engine().lane_state(0);
  EXPECT_GE(s.idle_ms, 0);
  EXPECT_LT(s.idle_ms, 60'000);
  // The line goes on: the same product again at the counts after the last.
  const int64_t shift = lines.lines.back().encoder() - lines.lines.front().encoder() + 1;
  for (auto& l : lines.lines) l.set_encoder(l.encoder() + shift);
  stream(ch, lines.lines);
  again.shutdown();
  std::set<int64_t> numbers;
  for (const auto& f : all_fillets(again.store())) {
    EXPECT_TRUE(numbers.insert(f.lane_fillet).second) << "two fillets " << f.lane_fillet;
    if (!before.count(f.lane_fillet)) EXPECT_GT(f.lane_fillet, *before.rbegin());
  }
  EXPECT_GT(numbers.size(), before.size());
}

TEST(Server, StreamsThatSendNothingTakeNoCredit) {
  test::TempDir t;
  const PlantConfig p = plant();
  ServerOptions o = options(t);
  o.engine.max_ingest_streams = 1000;  // past the default (256): these are what is tested
  RangexServer server(p, o);
  auto ch = connect(server);
  // 500 StreamLines calls that never send a line: once they cut a real feeder's credit from
  // 512 to 4.
  auto stub = pb::IngestService::NewStub(ch);
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<
      std::unique_ptr<grpc::ClientReaderWriter<pb::StreamLinesRequest, pb::StreamLinesResponse>>>
      idle;
  for (int k = 0; k < 500; ++k) {
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    idle.push_back(stub->StreamLines(contexts.back().get()));
  }
  ASSERT_TRUE(test::wait_until(120, [&] { return server.ingest_streams() == 500; }))
      << server.ingest_streams() << " of 500 streams open";
  const Lines lines(p, 1, 3);
  int max_credit = 0;
  for (const auto& a : stream(ch, lines.lines)) max_credit = std::max(max_credit, a.credit());
  // A quota among the plant's lanes at least (the queue divided by them), as without the
  // idle streams.
  const int quota = int(options(t).engine.queue_lines / p.lanes.size());
  EXPECT_GE(max_credit, quota / 2) << "the quota is " << quota;
  for (auto& c : contexts) c->TryCancel();
  for (auto& s : idle) s->Finish();
}

TEST(Server, AnIdleIngestStreamIsClosedAndABusyOneIsNot) {
  test::TempDir t;
  ServerOptions o = options(t);
  o.engine.stream_idle_s = 1.0;
  RangexServer server(plant(), o);
  auto stub = pb::IngestService::NewStub(connect(server));
  grpc::ClientContext idle_ctx, busy_ctx;
  auto idle = stub->StreamLines(&idle_ctx);
  auto busy = stub->StreamLines(&busy_ctx);
  // The busy stream asks for its credit every 0.1 s for 2 s: never idle that long.
  pb::StreamLinesResponse r;
  for (int k = 0; k < 20; ++k) {
    pb::StreamLinesRequest q;
    q.set_sequence(uint64_t(k));
    q.set_credit_query(true);
    ASSERT_TRUE(busy->Write(q)) << "the busy stream was closed after " << k * 100 << " ms";
    ASSERT_TRUE(busy->Read(&r));
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  busy->WritesDone();
  EXPECT_TRUE(busy->Finish().ok());
  // The idle one was ended long before, naming why (Read returns at once: it is over).
  EXPECT_FALSE(idle->Read(&r));
  const grpc::Status s = idle->Finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_NE(s.error_message().find("idle ingest stream closed"), std::string::npos)
      << s.error_message();
  // The server's side ends just after the client's (bounded wait).
  for (int k = 0; k < 500 && server.ingest_streams() > 0; ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(server.ingest_streams(), 0);
}

TEST(Server, StatisticsWarnBeforeTheStoreVolumeFills) {
  test::TempDir t;
  ServerOptions o = options(t);
  o.engine.store_reserve_mb = 1e12;  // more than any disk: the warning must show
  RangexServer server(plant(), o);
  const EngineStats s = server.engine().stats();
  const bool warned = std::any_of(s.warnings.begin(), s.warnings.end(), [](const std::string& w) {
    return w.find("store volume:") == 0 && w.find("below the reserve") != std::string::npos;
  });
  EXPECT_TRUE(warned) << ::testing::PrintToString(s.warnings);
  o.engine.store_reserve_mb = 0;  // off
  test::TempDir t2;
  o.data_dir = t2.str("data");
  RangexServer quiet(plant(), o);
  for (const std::string& w : quiet.engine().stats().warnings)
    EXPECT_EQ(w.find("store volume:"), std::string::npos) << w;
}

TEST(Server, ClientsPingNoFasterThanTheServerAccepts) {
  // A client pinging faster than the server's least accepted interval is cut off with GOAWAY
  // "too_many_pings" (gRPC's default interval is 5 minutes), a quiet subscription with it.
  // rangexd accepts pings every 5 s, with or without calls; rangex's clients ping every 10 s.
  // (gRPC 1.51 in process did not cut a subscription pinged every 200 ms even under its
  // default policy, so the cut itself is not reproduced here.)
  EXPECT_GE(kClientKeepaliveMs, 2 * ServerOptions{}.min_ping_interval_ms);
  EXPECT_LE(ServerOptions{}.min_ping_interval_ms, 10000);
}

TEST(Server, AQuietSubscriptionStaysOpenWithPingsAtTheAgreedRate) {
  // Half an hour of a quiet line, shortened by the settings: the server accepts pings every
  // 100 ms and pings every 300 ms itself; the client pings every 200 ms (twice the server's
  // least, as kClientKeepaliveMs is to min_ping_interval_ms), so the 6 s below carry some 30
  // client pings, as many as 5 minutes at 10 s. Then a fillet's decision still arrives.
  test::TempDir t;
  const PlantConfig p = plant();
  ServerOptions o = options(t);
  o.min_ping_interval_ms = 100;
  o.keepalive_ms = 300;
  RangexServer server(p, o);
  auto ch = rangex_channel(server.address(), {}, 2 * o.min_ping_interval_ms);
  auto results = pb::ResultsService::NewStub(ch);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));  // a hang bound
  auto reader = results->SubscribeFillets(&ctx, pb::SubscribeFilletsRequest());
  std::this_thread::sleep_for(std::chrono::seconds(6));
  const Lines lines(p, 2, 9);
  stream(connect(server), lines.lines);
  pb::SubscribeFilletsResponse r;
  ASSERT_TRUE(reader->Read(&r)) << "the quiet subscription was cut: "
                                << reader->Finish().error_message();
  EXPECT_EQ(r.fillet().lane(), 0);
  ctx.TryCancel();
  server.shutdown();
}

TEST(Server, HealthAndReflectionAnswer) {
  test::TempDir t;
  RangexServer server(plant(), options(t));
  auto ch = connect(server);
  std::string resp;
  ASSERT_TRUE(test::generic_unary(ch, "/grpc.health.v1.Health/Check", "", resp).ok());
  EXPECT_EQ(resp, std::string("\x08\x01", 2));  // status: SERVING
  for (const char* svc : {"rangex.v1.IngestService", "rangex.v1.ResultsService",
                          "rangex.v1.CalibrationService", "rangex.v1.ControlService"})
    EXPECT_EQ(test::health(ch, svc), 1) << svc;
  EXPECT_EQ(test::health(ch, "rangex.v1.Nothing"), -int(grpc::StatusCode::NOT_FOUND));
  // Reflection: list_services (field 7, empty string) on the bidirectional stream.
  grpc::GenericStub stub(ch);
  grpc::ClientContext ctx;
  grpc::CompletionQueue cq;
  auto call =
      stub.PrepareCall(&ctx, "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo", &cq);
  void* tag;
  bool ok;
  call->StartCall(reinterpret_cast<void*>(1));
  ASSERT_TRUE(cq.Next(&tag, &ok) && ok);
  grpc::Slice slice(std::string("\x3a\x00", 2));
  grpc::ByteBuffer req(&slice, 1), out;
  call->Write(req, reinterpret_cast<void*>(2));
  ASSERT_TRUE(cq.Next(&tag, &ok) && ok);
  call->Read(&out, reinterpret_cast<void*>(3));
  ASSERT_TRUE(cq.Next(&tag, &ok) && ok);
  std::vector<grpc::Slice> slices;
  out.Dump(&slices);
  std::string bytes;
  for (auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  for (const char* svc :
       {"rangex.v1.IngestService", "rangex.v1.ResultsService", "rangex.v1.CalibrationService",
        "rangex.v1.ControlService", "grpc.health.v1.Health"})
    EXPECT_NE(bytes.find(svc), std::string::npos) << svc;
  ctx.TryCancel();
  grpc::Status st;
  call->Finish(&st, reinterpret_cast<void*>(4));
  cq.Next(&tag, &ok);
  cq.Shutdown();
  while (cq.Next(&tag, &ok)) {
  }
}

TEST(DecisionNames, EveryDecisionHasOneNameBothWays) {
  const pb::Decision all[] = {pb::DECISION_PASS, pb::DECISION_REJECT, pb::DECISION_NOT_INSPECTED};
  std::set<std::string> names;
  for (const pb::Decision d : all) {
    const std::string name = decision_name(d);
    EXPECT_FALSE(name.empty()) << d;
    EXPECT_EQ(decision_from_name(name), d) << name;
    names.insert(name);
  }
  EXPECT_EQ(names, (std::set<std::string>{"pass", "reject", "not_inspected"}));
  // Every value the proto declares is named, UNSPECIFIED alone by nothing.
  const auto* e = pb::Decision_descriptor();
  for (int k = 0; k < e->value_count(); ++k) {
    const auto d = pb::Decision(e->value(k)->number());
    EXPECT_EQ(std::string(decision_name(d)).empty(), d == pb::DECISION_UNSPECIFIED)
        << e->value(k)->name();
  }
  EXPECT_EQ(decision_from_name("PASS"), pb::DECISION_UNSPECIFIED);
  EXPECT_EQ(decision_from_name(""), pb::DECISION_UNSPECIFIED);
}

namespace {
// A refusal of a bad argument, naming what is wrong.
void expect_refused(const grpc::Status& s, const std::string& why) {
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << why;
  EXPECT_EQ(s.error_message(), why);
}
}  // namespace

// The ids and names a client gives are listed, audited and logged, one line each: an empty
// one, one of more than 100 bytes and one holding a control character are refused, naming
// which; one of 100 bytes of UTF-8 is taken.
TEST(Server, IdsAndNamesAreOneLineOfAtMostAHundredBytes) {
  test::TempDir t;
  RangexServer server(plant(), options(t));
  auto ch = connect(server);
  auto cal = pb::CalibrationService::NewStub(ch);
  auto control = pb::ControlService::NewStub(ch);
  auto upload = [&](const std::string& id) {
    grpc::ClientContext c;
    pb::UploadCalibrationRequest up;
    up.set_lane(0);
    up.set_id(id);
    up.set_yaml("laser_plane: {normal: [0, 1, 0], offset_mm: 0.05}\n");
    pb::UploadCalibrationResponse r;
    return cal->UploadCalibration(&c, up, &r);
  };
  const std::pair<std::string, std::string> refused[] = {
      {"", "a calibration's id is empty"},
      {std::string(101, 'x'), "a calibration's id is 101 bytes, more than the 100 allowed"},
      {"recal\n2026", "a calibration's id 'recal...' holds the control character 0x0A at 5"}};
  for (const auto& [id, why] : refused) expect_refused(upload(id), why);
  std::string longest;
  while (longest.size() < 100) longest += "\xc3\xa6";  // ae, two bytes each
  EXPECT_TRUE(upload(longest).ok());
  {
    grpc::ClientContext c;
    pb::UploadLearnedSettingsRequest up;
    up.set_lane(0);
    up.set_id("live\t3");
    pb::UploadLearnedSettingsResponse r;
    expect_refused(control->UploadLearnedSettings(&c, up, &r),
                   "learned settings' id 'live...' holds the control character 0x09 at 4");
  }
  {  // the same for a learning on the live lane, before it waits for a fillet
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
    pb::LearnProductRequest q;
    q.set_lane(0);
    q.set_id(std::string(120, 'v'));
    pb::LearnProductResponse r;
    expect_refused(control->LearnProduct(&c, q, &r),
                   "learned settings' id is 120 bytes, more than the 100 allowed");
  }
  {
    grpc::ClientContext c;
    pb::StartRecordingRequest q;
    q.set_minutes(1);
    q.set_name("shift\r");
    pb::StartRecordingResponse r;
    expect_refused(control->StartRecording(&c, q, &r),
                   "a recording's name 'shift...' holds the control character 0x0D at 5");
  }
}

// A camera's vendor and model are bytes of its registers, a database names its errors in its
// own encoding, a data folder may be any path: such text reaches the messages as UTF-8 (U+FFFD
// for a byte that is not), or no client could read GetServerInfo or GetStatistics at all.
TEST(Server, TextFromOutsideReachesTheMessagesAsUtf8) {
  const std::string fffd = "\xEF\xBF\xBD";
  LaneState lane;
  lane.config = default_plant_config(1).lanes[0];
  SensorState cam;
  cam.role = "cam0";
  cam.device = "cam-\xff";
  cam.description = "Vend\xe4r M1 #12";
  cam.error = "lost \xc3";
  lane.sensors = LaneSensors{};
  lane.sensors->devices.push_back(cam);
  lane.plc = "unreachable: \xe4 timeout";
  pb::LaneInfo info;
  fill(&info, lane);
  pb::LaneInfo info_back;
  ASSERT_TRUE(info_back.ParseFromString(info.SerializeAsString()));
  const pb::SensorDevice& d = info_back.sensors().devices(0);
  EXPECT_EQ(d.device(), "cam-" + fffd);
  EXPECT_EQ(d.description(), "Vend" + fffd + "r M1 #12");
  EXPECT_EQ(d.error(), "lost " + fffd);
  EXPECT_EQ(info_back.plc_state(), "unreachable: " + fffd + " timeout");

  EngineStats st;
  st.plc = PlcStatus{};
  st.plc->error = "\xe4 timeout";
  st.forwarding = ForwarderStatus{};
  st.forwarding->last_error = "FATAL: Passwort f\xfcr Benutzer";
  st.recording.name = "shift";
  st.recording.dir = "/data/\xff/shift";
  st.warnings.push_back("lane 0 cam0 (cam-\xff) lost: lost \xc3");
  pb::GetStatisticsResponse stats;
  fill(&stats, st);
  pb::GetStatisticsResponse stats_back;
  ASSERT_TRUE(stats_back.ParseFromString(stats.SerializeAsString()));
  EXPECT_EQ(stats_back.plc().error(), fffd + " timeout");
  EXPECT_EQ(stats_back.forwarding().error(), "FATAL: Passwort f" + fffd + "r Benutzer");
  EXPECT_EQ(stats_back.recording().dir(), "/data/" + fffd + "/shift");
  ASSERT_EQ(stats_back.warnings_size(), 1);
  EXPECT_EQ(stats_back.warnings(0), "lane 0 cam0 (cam-" + fffd + ") lost: lost " + fffd);
}

// A PLC whose program maps fewer registers than plant.yaml's plc section: the PLC answers,
// so it is connected, and the registers it refuses are named to every client, on every lane,
// in /metrics and on the dashboard's tiles.
TEST(Server, APlcThatRefusesRegistersIsNamedToEveryClient) {
  test::TempDir t;
  PlantConfig p = default_plant_config(2);
  p.plc.heartbeat_ms = 20;
  SimPlc plc(p.plc);
  plc.set_registers(12);  // lane 0's state (10, 11), not lane 1's (12, 13)
  p.plc.address = "127.0.0.1:" + std::to_string(plc.port());
  RangexServer server(p, options(t));
  auto stub = pb::ControlService::NewStub(connect(server));
  pb::GetStatisticsResponse stats;
  ASSERT_TRUE(wait_until(20, [&] {
    grpc::ClientContext ctx;
    stats.Clear();
    return stub->GetStatistics(&ctx, {}, &stats).ok() && !stats.plc().refused().empty();
  }));
  EXPECT_TRUE(stats.plc().connected());
  EXPECT_TRUE(stats.plc().error().empty()) << stats.plc().error();
  const std::string& refused = stats.plc().refused();
  for (const char* said : {"refuses registers 12..13", "a lane's state", "plant.yaml"})
    EXPECT_NE(refused.find(said), std::string::npos) << said << ": " << refused;
  EXPECT_NE(std::find(stats.warnings().begin(), stats.warnings().end(), refused),
            stats.warnings().end());
  grpc::ClientContext ctx;
  pb::ListLanesResponse lanes;
  ASSERT_TRUE(stub->ListLanes(&ctx, {}, &lanes).ok());
  ASSERT_EQ(lanes.lanes_size(), 2);
  for (const pb::LaneInfo& l : lanes.lanes())
    EXPECT_EQ(l.plc_state(), "refusing: " + refused) << "lane " << l.id();
  EXPECT_EQ(plc.lane_state(0), PackMl::kIdle);  // the state it maps was written

  MetricsInput m;
  m.stats = server.engine().stats();
  m.lanes = server.engine().lanes();
  const std::string metrics = prometheus_text(m);
  EXPECT_NE(metrics.find("rangex_plc_refusing{plc=\"" + p.plc.address + "\"} 1\n"),
            std::string::npos)
      << metrics;
  // A lane fed a moment ago shows it beside its light.
  LaneState fed = m.lanes[1];
  fed.fed = true;
  fed.idle_ms = 100;
  PlantHistory history;
  const nlohmann::json tile = lane_json(fed, history, "cpu");
  EXPECT_EQ(tile.at("light"), "amber") << tile.dump();
  EXPECT_EQ(tile.at("light_reason"), refused) << tile.dump();
}

TEST(Server, TheLargestMessageTakenFollowsThePlantsLines) {
  // At least 16 MiB for the uploads; past that, eight of the largest line (four are still
  // refused in-band as OVERSIZED) and the message's framing.
  EXPECT_EQ(max_message_bytes({}), 16 << 20);
  EXPECT_EQ(max_message_bytes({{0, 640, 200, 480, 1}}), 16 << 20);  // the demo plant's lanes
  const LaneShape big{3, 4096, 2048, 2048, 2};                      // 16 MiB + 8 kB a line
  EXPECT_EQ(line_bytes(big), size_t(16785408));
  EXPECT_EQ(max_message_bytes({{0, 640, 200, 480, 1}, big}), 8 * 16785408 + (64 << 10));
  EXPECT_EQ(max_message_bytes({{0, 65536, 65536, 1, 1}}), INT_MAX);  // clamped, not wrapped
}
