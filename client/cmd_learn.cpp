// learn: product learning on a recording of the plant's own clean product. The
// recording is replayed through the same line stages and inspection as `process`; each
// fillet's detection extremes per thickness band are fitted with an extreme-value model per
// lane (pipeline/product_learning.h), the thresholds that meet the lane's false-reject
// budget are written into a copy of the plant configuration, and the sensitivity they buy
// is measured with test pieces injected into the same fillets (pipeline/sensitivity.h).
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "args.h"
#include "backend_args.h"
#include "calib/lane_calibration_file.h"
#include "commands.h"
#include "core/error.h"
#include "core/json_text.h"
#include "learn_report.h"
#include "offline/plant_run.h"
#include "offline/replay.h"
#include "pipeline/lane_learning.h"
#include "pipeline/learned_report.h"
#include "progress_bar.h"

namespace fs = std::filesystem;

namespace rangex::cli {

namespace {

// The plant configuration at `config` with each learned lane's inspection section replaced.
std::string learned_plant_yaml(const std::string& config,
                               const std::vector<std::pair<int, LearnedDetection>>& learned) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(config);
  } catch (const YAML::Exception& e) {
    fail(config, ": not valid YAML: ", e.what());
  }
  for (const auto& [lane, L] : learned) {
    bool found = false;
    for (YAML::Node ln : root["lanes"])
      if (ln["id"] && ln["id"].as<int>() == lane) {
        // A lane's own inspection section replaces lane_defaults' whole: it starts as a copy
        // of the defaults', so that what the plant set there (and the learning ran with)
        // still holds beside the thresholds.
        if (!ln["inspection"] && root["lane_defaults"] && root["lane_defaults"]["inspection"])
          ln["inspection"] = YAML::Clone(root["lane_defaults"]["inspection"]);
        ln["inspection"]["false_reject_target"] = L.target_frr;
        ln["inspection"]["learned"] = YAML::Load(learned_detection_yaml(L));
        found = true;
      }
    if (!found) fail(config, ": lanes: no lane ", lane, " to hold what was learned for it");
  }
  YAML::Emitter out;
  out << root;
  return std::string(
             "# Written by rangexctl learn: the plant configuration with learned "
             "inspection thresholds.\n") +
         out.c_str() + "\n";
}

// One lane's learning fillets, from a replay or an in-memory simulation.
struct LaneFillets {
  int lane = 0;
  LearningSet set;
};

std::vector<LaneFillets> from_replay(const std::vector<LaneReplay>& lanes) {
  std::vector<LaneFillets> out;
  for (const LaneReplay& r : lanes) {
    out.push_back({r.lane, {}});
    for (const InspectedFillet& f : r.fillets) out.back().set.add(f.result, f.image);
  }
  return out;
}

// A learning run in memory: the plant's lanes simulated with no bone, each fillet
// inspected as a recording's would be (no frames written).
std::vector<LaneFillets> simulated_fillets(const PlantConfig& plant, const Args& a,
                                           const ReplayOptions& opt) {
  sim::SimulationParams sp;
  sp.lanes = int(a.integer("lanes", long(plant.lanes.size())));
  sp.scene.fillets = int(a.integer("fillets", 40));
  sp.seed = uint64_t(a.integer("seed", 1));
  if (a.has("physics")) sp.physics = sim::load_plant_physics(a.require("physics"));
  sp.physics.bones.probability = 0;
  std::map<int, LaneFillets> by_lane;
  std::mutex mu;
  PlantRunOptions po;
  po.backend = opt.backend;
  po.threads = int(std::max(1u, std::thread::hardware_concurrency()));
  po.on_fillet = [&](const InspectedFillet& f) {
    std::lock_guard<std::mutex> lock(mu);
    LaneFillets& l = by_lane[f.result.lane];
    l.lane = f.result.lane;
    l.set.add(f.result, f.image);
  };
  ProgressBar bar("simulate");
  run_simulated_plant(plant, sp, po, [&](int64_t d, int64_t t) { bar.update(d, t); });
  std::vector<LaneFillets> lanes;
  for (auto& [id, l] : by_lane) lanes.push_back(std::move(l));
  return lanes;
}

// The learned thresholds' sensitivity claims, checked on another recording's fillets of the
// lane; printed, and returned for the report.
nlohmann::json held_out_check(const LaneReplay& c, const LaneLearning& ll,
                              const SensitivityOptions& so, const std::string& dir) {
  ProgressBar cbar("sensitivity (check)");
  const HeldOutCheck hc =
      check_held_out(c.fillets, ll, so, [&](int d, int t) { cbar.update(d, t); });
  std::printf(
      "  held-out check on %d fillets of %s: %d of %zu claims by band held, %d contradicted\n",
      hc.fillets, dir.c_str(), hc.held(), hc.checks.size(), hc.contradicted());
  for (const ClaimCheck& k : hc.checks)
    if (!k.held) std::printf("    %s\n", claim_check_text(k).c_str());
  for (const StatedCheck& k : hc.stated)
    std::printf("    \"%s\": %s\n", k.claim.text.c_str(), claim_check_text(k).c_str());
  return nlohmann::json::parse(claim_checks_json(dir, hc.fillets, hc.checks, hc.stated, hc.cells));
}

// How the lanes are learned, from the command line: the fit's options (each lane's target,
// confidence and tail are set per lane, in learn_lanes), the test pieces', the targets traded
// off, the version's name, where the fillets came from and where the report goes.
struct LearnRun {
  LearnOptions lo;
  SensitivityOptions so;
  std::vector<double> tradeoff;
  std::string version, source;
  fs::path report_dir;
};

LearnRun learn_run(const Args& a, const std::string& source, const std::string& out) {
  LearnRun run;
  run.source = source;
  run.report_dir =
      a.get("report",
            (fs::path(out).parent_path() / (fs::path(out).stem().string() + ".report")).string());
  run.lo.bootstrap = int(a.number("bootstrap", 100, 20, 10000));
  run.lo.min_fillets = int(a.number("min-fillets", 30, 10, 100000));
  if (a.has("keep")) run.lo.checked_clean = checked_clean_fillets(a.get("keep", ""));
  if (a.has("tradeoff")) run.tradeoff = tradeoff_targets(a.get("tradeoff", ""));
  run.so.material.excess_ratio = a.number("excess-ratio", run.so.material.excess_ratio, 0.05, 100);
  run.so.material.excess_per_mm = a.number("excess-per-mm", 0, 0, 10);
  // Without --force a failed learning writes no configuration: it is refused without the
  // test pieces, most of a learning's time (the report says the sensitivity was not measured).
  run.so.when_learning_failed = a.flag("force");
  run.version = a.get("version", learning_version_name());
  return run;
}

// Learns each lane, checks its claims on the held-out fillets (`check`, replayed from
// `check_dir`), writes its plots and says what it learned. Each lane's entry goes into
// report["lanes"]; returns each lane's learned settings, and `all_ok` whether every lane's
// learning passed.
std::vector<std::pair<int, LearnedDetection>> learn_lanes(const Args& a, const PlantConfig& plant,
                                                          const std::vector<LaneFillets>& lanes,
                                                          const std::vector<LaneReplay>& check,
                                                          const std::string& check_dir,
                                                          LearnRun& run, nlohmann::json& report,
                                                          bool& all_ok) {
  std::vector<std::pair<int, LearnedDetection>> learned;
  LearnOptions& lo = run.lo;
  for (const LaneFillets& r : lanes) {
    const LaneConfig& lane = plant.lane(r.lane);
    lo.target_frr = a.number("target-frr", lane.inspection.false_reject_target, 1e-5, 0.2);
    lo.confidence = a.number("confidence", lo.confidence, 0.5, 0.999);
    lo.tail_from = a.number("tail-from", lo.tail_from, 0, 0.95);
    lo.spread_by_thickness = lane.inspection.spread_by_thickness;
    lo.rim_walls = lane.inspection.rim_walls;
    std::printf("lane %d: %zu fillets inspected (%d not inspected, left out); fitting ...\n",
                r.lane, r.set.size(), r.set.not_inspected);
    std::fflush(stdout);
    // The sensitivity the thresholds buy, and what other false-reject targets would buy, is
    // measured on the same fillets and test pieces (the report says so; a held-out check is
    // --check, on fillets it did not learn from).
    ProgressBar sbar(run.tradeoff.empty() ? "sensitivity" : "sensitivity, every target");
    const LaneLearning ll = learn_lane(
        r.set, lane.inspection, lo, run.so, run.version,
        run.source + " lane " + std::to_string(r.lane), [&](int d, int t) { sbar.update(d, t); },
        run.tradeoff);
    const ProductLearning& L = ll.learning;
    const SensitivityResult& sens = ll.sensitivity;
    const std::vector<TradeoffPoint>& points = ll.tradeoff;
    nlohmann::json lane_json = nlohmann::json::parse(learned_report_json(r.lane, L, sens, points));
    for (const LaneReplay& c : check) {
      if (c.lane != r.lane || sens.inspections == 0) continue;
      lane_json["held_out_check"] = held_out_check(c, ll, run.so, check_dir);
    }
    report["lanes"].push_back(lane_json);
    write_learn_plots(run.report_dir, r.lane, L, sens);
    std::printf("%s", learn_summary_text(r.lane, L, sens).c_str());
    if (!points.empty()) std::printf("%s", tradeoff_text(ll, points).c_str());
    all_ok = all_ok && L.ok;
    learned.push_back({r.lane, L.learned});
  }
  return learned;
}

// The plant's configuration with each lane's learned section, written to `out` and read back
// as a plant configuration.
void write_learned_plant(const std::string& config, const std::string& out,
                         const std::vector<std::pair<int, LearnedDetection>>& learned) {
  const std::string text = learned_plant_yaml(config, learned);
  {
    std::ofstream o(out);
    o << text;
    if (!o) fail(out, ": cannot write");
  }
  load_plant_config(out);
}

}  // namespace

int cmd_learn(int argc, char** argv) {
  const Args a(argc, argv, 2, {"force", "simulate"},
               {"out",     "config",   "target-frr", "confidence",   "lanes",         "calibration",
                "report",  "version",  "bootstrap",  "excess-ratio", "excess-per-mm", "min-fillets",
                "backend", "device",   "check",      "fillets",      "seed",          "physics",
                "keep",    "tradeoff", "tail-from"});
  const char* usage =
      "learn RECORDING --out PLANT.yaml [--config plant.yaml] [--target-frr 0.003] "
      "[--confidence 0.9] [--tail-from 0.5] [--lanes 0,1] [--calibration F] [--report DIR] "
      "[--version NAME] [--excess-ratio 2] [--check RECORDING] [--keep LANE:FILLET,...] "
      "[--tradeoff 0.001,0.01] [--force]\n"
      "   or: learn --simulate --out PLANT.yaml [--lanes N] [--fillets M] [--seed S] "
      "[--physics F] (a clean simulated plant, in memory)";
  const bool simulate = a.flag("simulate");
  a.expect_positionals(simulate ? 0 : 1, usage);
  const std::string config = config_path(a.get("config", ""));
  PlantConfig plant = load_plant_config(config);
  if (a.has("calibration")) apply_calibration_option(plant, a.get("calibration", ""));
  std::unique_ptr<RecordingReader> rec;
  if (!simulate) rec = std::make_unique<RecordingReader>(a.positional(0, "recording folder"));
  const std::string out = a.require("out");
  LearnRun run = learn_run(a, simulate ? "a clean simulated plant" : rec->dir(), out);
  ReplayOptions opt;
  opt.keep_images = true;
  opt.baseline = false;
  opt.recalibrated = a.has("calibration");
  opt.backend = backend_request(a, plant.backend);
  if (a.has("lanes") && !simulate) opt.lanes = a.lane_ids("lanes");
  // Learned afresh: the extremes are taken in the default bands, whatever was learned before.
  for (auto& l : plant.lanes) l.inspection.learned = LearnedDetection{};
  std::vector<LaneFillets> lanes;
  if (simulate) {
    lanes = simulated_fillets(plant, a, opt);
  } else {
    ProgressBar bar("replay");
    lanes = from_replay(
        replay_recording(*rec, plant, opt, [&](int64_t d, int64_t t) { bar.update(d, t); }));
  }
  // Held-out fillets (another recording of the same product) on which the sensitivity
  // claims are checked with the learned thresholds.
  std::vector<LaneReplay> check;
  std::unique_ptr<RecordingReader> check_rec;
  if (a.has("check")) {
    check_rec = std::make_unique<RecordingReader>(a.get("check", ""));
    ProgressBar bar("replay (check)");
    check =
        replay_recording(*check_rec, plant, opt, [&](int64_t d, int64_t t) { bar.update(d, t); });
  }
  fs::create_directories(run.report_dir);
  nlohmann::json report = {{"recording", run.source}, {"config", config}, {"version", run.version}};
  bool all_ok = true;
  const auto learned =
      learn_lanes(a, plant, lanes, check, check_rec ? check_rec->dir() : "", run, report, all_ok);
  report["ok"] = all_ok;
  std::ofstream(run.report_dir / "learn.json") << json_dump(report, 2) << "\n";
  std::printf(
      "report: %s/learn.json and lane*_thresholds.png, lane*_sensitivity.png, lane*_qq.png\n",
      run.report_dir.c_str());
  if (!all_ok && !a.flag("force")) {
    std::fprintf(stderr,
                 "learning failed (see the problems above): %s not written (--force writes it, "
                 "with the sensitivity its thresholds buy)\n",
                 out.c_str());
    return 2;
  }
  write_learned_plant(config, out, learned);
  std::printf("wrote %s (version %s)\n", out.c_str(), run.version.c_str());
  return all_ok ? 0 : 2;
}

}  // namespace rangex::cli
