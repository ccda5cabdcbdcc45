// rangexctl learned upload|list|activate|learn: learned inspection settings on rangexd,
// versioned and audited, and a live lane's learning.
#include <grpcpp/grpcpp.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "learn_report.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "remote_call.h"

namespace rangex::cli {

namespace pb = rangex::v1;

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
  check_status(stub.LearnProduct(&long_ctx, req, &resp), "learn");
  const pb::LearnedSettingsInfo& s = resp.settings();
  passed = s.report_status() == "passed";
  std::string out = learned_info_text(s);
  if (req.tradeoff_targets_size() > 0) {
    // What the other targets would buy, from the stored report.
    UnaryCall lctx;
    pb::ListLearnedSettingsRequest lreq;
    lreq.set_lane(s.lane());
    lreq.set_full(true);
    pb::ListLearnedSettingsResponse lresp;
    check_status(stub.ListLearnedSettings(&lctx, lreq, &lresp), "list");
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

// The lane's inspection.learned section of a plant configuration rangexctl learn wrote,
// with the report it wrote beside it (--report, else PLANT.report/learn.json).
void learned_upload(const Args& a, pb::ControlService::Stub& stub) {
  UnaryCall ctx;
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
    if (ln["id"] && ln["id"].as<int>() == lane && ln["inspection"] && ln["inspection"]["learned"]) {
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
  check_status(stub.UploadLearnedSettings(&ctx, req, &resp), "upload");
  std::printf("uploaded learned settings '%s' for lane %d; report: %s\n",
              resp.settings().id().c_str(), resp.settings().lane(),
              resp.settings().report_status().c_str());
}

void learned_list(const Args& a, pb::ControlService::Stub& stub) {
  UnaryCall ctx;
  pb::ListLearnedSettingsRequest req;
  req.set_lane(int(a.integer("lane", -1)));
  req.set_full(a.flag("full"));
  pb::ListLearnedSettingsResponse resp;
  check_status(stub.ListLearnedSettings(&ctx, req, &resp), "list");
  // An empty answer says so: a blank screen reads as a command that did nothing.
  if (resp.settings().empty())
    std::printf("no learned settings%s (rangexctl learned upload, or learned learn)\n",
                req.lane() >= 0 ? (" for lane " + std::to_string(req.lane())).c_str() : "");
  for (const auto& s : resp.settings()) {
    std::fputs(learned_info_text(s).c_str(), stdout);
    if (a.flag("full")) std::printf("%s\n", s.yaml().c_str());
  }
}

void learned_activate(const Args& a, pb::ControlService::Stub& stub) {
  UnaryCall ctx;
  pb::ActivateLearnedSettingsRequest req;
  req.set_lane(int(a.integer("lane", 0)));
  req.set_id(a.require("id"));
  req.set_force(a.flag("force"));
  pb::ActivateLearnedSettingsResponse resp;
  check_status(stub.ActivateLearnedSettings(&ctx, req, &resp), "activate");
  std::printf(
      "learned settings '%s' of lane %d activated; they take over at the next batch without "
      "a fillet in progress\n",
      req.id().c_str(), req.lane());
}

// --lanes 0,1,2: every lane listed learns its own product at once, from its own next
// fillets (one call each). 2 when a lane's learning failed (stored, not to be activated).
int learned_learn(const Args& a, pb::ControlService::Stub& stub) {
  std::vector<int> lanes;
  if (a.has("lanes")) {
    if (a.has("lane")) fail("give --lane L or --lanes L,L,..., not both");
    for (int l : a.lane_ids("lanes")) {
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
        text = learn_live(stub, mine, timeout, passed);
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
  return 0;
}

}  // namespace

// `rangexctl learned upload|list|activate|learn`: learned inspection settings on rangexd.
int cmd_learned(int argc, char** argv) {
  if (argc < 3) fail("usage: learned upload|list|activate|learn ...");
  const std::string verb = argv[2];
  const Args a(argc, argv, 3, {"force", "full"},
               remote_options({"lane", "lanes", "id", "file", "report", "fillets", "target-frr",
                               "min-fillets", "timeout", "tradeoff", "relearn-from", "keep"}));
  auto stub = pb::ControlService::NewStub(server_channel(a));
  if (verb == "upload")
    learned_upload(a, *stub);
  else if (verb == "list")
    learned_list(a, *stub);
  else if (verb == "activate")
    learned_activate(a, *stub);
  else if (verb == "learn")
    return learned_learn(a, *stub);
  else
    fail("learned: unknown verb '", verb, "' (upload, list, activate, learn)");
  return 0;
}

}  // namespace rangex::cli
