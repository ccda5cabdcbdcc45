// eval-matrix: detection on plants the project did not simulate. Each plant
// variant (config/variants/*.yaml) is calibrated from its own calibration scenes (the pin
// phantom for the fan beam and the detector's blur, blocks for the registration), its plant
// is simulated with its physics, K1/K2 are fitted on that plant's own recording, and the
// recording is replayed with that calibration and evaluated against its truth, beside the
// X-ray-only baseline. Held-out variants are reported apart. A benchmark (minutes per
// variant); the tests run a slice.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "args.h"
#include "calib/lane_calibration_file.h"
#include "commands.h"
#include "core/error.h"
#include "core/learned_detection.h"
#include "core/recording.h"
#include "core/text_file.h"
#include "eval_bone_run.h"
#include "eval_claims.h"
#include "eval_matrix_report.h"
#include "eval_steps.h"
#include "f32_file.h"
#include "learning_check.h"
#include "offline/detection_eval.h"
#include "offline/evaluation.h"
#include "offline/fillet_records.h"
#include "offline/fragment_chance.h"
#include "offline/miss_margin.h"
#include "offline/recorded_drift.h"
#include "offline/replay.h"

namespace fs = std::filesystem;

namespace rangex::cli {

namespace {

// Scans are large (256 kB of camera frames a line, about 130 MB a fillet): each goes as soon
// as nothing reads it any more; the results, the calibration and its reports stay.
void drop_scans(const fs::path& dir, std::initializer_list<const char*> scans,
                const MatrixOptions& mo) {
  if (!mo.keep)
    for (const char* d : scans) fs::remove_all(dir / d);
}

// The steps of one variant's run: its folder, log, physics and calibration, and the plant
// configuration every step reads, as this command does.
struct VariantSteps {
  const VariantRun& v;
  const std::string& config;
  const MatrixOptions& mo;
  std::string at(const std::string& name) const { return v.at(name); }
  // What the learning reported (its JSON), which the claims and the row are read from.
  std::string learn_report() const { return (v.dir / "learned.report" / "learn.json").string(); }
  void step(std::vector<std::string> args) const {
    if (!config.empty()) args.insert(args.end(), {"--config", config});
    run_step(v.log, std::move(args));
  }
  // More fillets inspected with what the variant learned, in parts of at most frr_part
  // fillets: the clean run and the bone run.
  PartRun more() const {
    PartRun p;
    p.dir = v.dir, p.log = v.log, p.physics = v.physics, p.cal = v.cal;
    p.learned = at("learned.yaml"), p.config = config;
    p.part = mo.frr_part, p.keep = mo.keep;
    return p;
  }
};

// The plant's own calibration (fan beam and blur from its pins, registration from its
// blocks, K1/K2 from its own recording), then its plant simulated and processed.
void calibrate_and_process(const VariantSteps& s) {
  const std::string &V = s.v.physics, &cal = s.v.cal;
  s.step({"calib", "simulate", "pins", s.at("pins"), "--physics", V});
  s.step({"calib", "simulate", "blocks", s.at("blocks"), "--physics", V});
  s.step({"calib", "xray", s.at("pins"), "--out", cal});
  s.step({"calib", "registration", s.at("blocks"), "--calibration", cal});
  drop_scans(s.v.dir, {"pins", "blocks"}, s.mo);
  s.step({"simulate", "--out", s.at("rec"), "--lanes", "1", "--fillets",
          std::to_string(s.mo.fillets), "--seed", std::to_string(s.mo.seed), "--physics", V});
  s.step({"calib", "scatter", s.at("rec"), "--calibration", cal});
  s.step({"process", s.at("rec"), "--out", s.at("out"), "--images", "none", "--calibration", cal});
}

// The plant's own product learned from clean fillets of another seed (cartilage and all,
// bone left out), its claims checked on a third seed, then the plant inspected with it and
// the clean run.
void learn_and_process(const VariantSteps& s, MatrixRow& r) {
  const MatrixOptions& mo = s.mo;
  const long seed = mo.seed;
  const std::string &V = s.v.physics, &cal = s.v.cal, &log = s.v.log;
  s.step({"simulate", "--out", s.at("learn_rec"), "--lanes", "1", "--fillets",
          std::to_string(mo.learn_fillets), "--seed", std::to_string(seed + 1000), "--physics", V,
          "--clean"});
  s.step({"simulate", "--out", s.at("check_rec"), "--lanes", "1", "--fillets",
          std::to_string(mo.check_fillets), "--seed", std::to_string(seed + 2000), "--physics", V,
          "--clean"});
  // A failed learning's named fillets checked as a plant would (client/learning_check.h):
  // clean ones learned again with, bony ones left out.
  std::vector<std::string> extra = {"--calibration",   cal,         "--check",
                                    s.at("check_rec"), "--version", "matrix-" + r.name};
  if (!s.config.empty()) extra.insert(extra.end(), {"--config", s.config});
  if (!mo.confidence.empty()) extra.insert(extra.end(), {"--confidence", mo.confidence});
  if (!mo.tail_from.empty()) extra.insert(extra.end(), {"--tail-from", mo.tail_from});
  r.check = learn_as_a_plant_would(log, s.at("learn_rec"), s.at("learned.yaml"), extra);
  drop_scans(s.v.dir, {"learn_rec", "check_rec"}, mo);
  // The learned configuration in place of the plant's (run_step adds no --config here).
  run_step(log, {"process", s.at("rec"), "--out", s.at("out_learned"), "--images", "none",
                 "--calibration", cal, "--config", s.at("learned.yaml")});
  r.learned_run = true;
  // The clean run in parts of at most frr_part fillets (seeds 3000, 3100, ... past the
  // plant's), each part's scan dropped once inspected.
  PartRun clean = s.more();
  clean.rec = "frr_rec", clean.out = "out_frr";
  clean.fillets = mo.frr_fillets, clean.seed = seed + 3000;
  run_in_parts(clean, {});
}

// The clean run's parts as their records, counted into `r` (fillets, rejects, detections).
std::vector<RecordSet> read_clean_runs(const fs::path& dir, int lane, MatrixRow& r) {
  std::vector<RecordSet> clean_runs;
  for (int part = 0; fs::is_directory(dir / ("out_frr" + std::to_string(part))); ++part) {
    const RecordSet& clean = clean_runs.emplace_back(read_records(
        (dir / ("out_frr" + std::to_string(part)) / ("lane" + std::to_string(lane))).string(), ""));
    r.frr_fillets += int(clean.fillets.size());
    for (const auto& f : clean.fillets)
      r.frr_rejected += f.decision != "pass", r.frr_not_inspected += f.decision == "not_inspected";
    // Bone detections only: air pockets (marbling looks like them) do not reject.
    r.frr_fragments += int(std::count_if(clean.fragments.begin(), clean.fragments.end(),
                                         [](const auto& f) { return f.kind == "bone"; }));
  }
  return clean_runs;
}

// What the learning reported (learn.json): ok, its fillets, those it named, its sensitivity
// and the check of its claims; with the clean run and what the drift monitor said over it.
void read_learning(const VariantSteps& s, int lane, MatrixRow& r) {
  const std::string report = s.learn_report();
  const auto j = nlohmann::json::parse(read_text_file(report));
  for (const auto& l : j.at("lanes")) {
    r.learn_ok = l.at("ok").get<bool>();
    r.learn_fillets = l.at("fillets").get<int>();
    if (l.contains("flagged_fillets")) r.learn_flagged = int(l.at("flagged_fillets").size());
    for (const auto& t : l.at("sensitivity").at("summary")) r.sensitivity.push_back(t);
    const std::vector<RecordSet> clean_runs = read_clean_runs(s.v.dir, lane, r);
    if (const LearnedDetection L =
            load_plant_config(s.at("learned.yaml")).lane(lane).inspection.learned;
        !clean_runs.empty() && L.active()) {
      r.drift = recorded_drift(L, clean_runs, lane);
      r.drift_sentence = drift_sentence(lane, r.drift);
    }
    if (l.contains("held_out_check")) {
      const nlohmann::json& h = l["held_out_check"];
      r.claims = h["claims"].get<int>(), r.claims_held = h["held"].get<int>();
      r.claims_contradicted = h.value("contradicted", 0);
      for (const auto& k : h["checks"])
        if (!k["held"].get<bool>()) r.claims_not_held.push_back(k.value("text", std::string()));
      r.stated = h["stated"].get<int>(), r.stated_held = h["stated_held"].get<int>();
      for (const auto& k : h["stated_checks"])
        r.stated_found += k["found"].get<int>(), r.stated_injected += k["injected"].get<int>();
    }
  }
}

// The learned run judged against the truth, each miss's margin and each fragment's chance
// measured, the bone run, and the report's claims held against their fragments.
void evaluate_learned(const VariantSteps& s, const RecordingReader& rec, const LaneConfig& lc,
                      const VariantTruth& vt, MatrixRow& r) {
  const int lane = rec.info().lanes.at(0);
  const fs::path ll = s.v.dir / "out_learned" / ("lane" + std::to_string(lane));
  add_lane(r.learned, vt.fragments, vt.fillets, read_records(ll.string(), ""), &vt.edges);
  finish(r.learned);
  // What finding each miss would cost: its fillet inspected again with the learned
  // thresholds scaled down (offline/miss_margin.h), on the recording replayed as the
  // learned run was.
  auto margins = [&](DetectionEval& e, const RecordingReader& from) {
    PlantConfig lp = load_plant_config(s.at("learned.yaml"));
    apply_calibration_option(lp, s.v.cal);
    ReplayOptions ro;
    ro.keep_images = true, ro.baseline = false, ro.recalibrated = true;
    ro.lanes = {from.info().lanes.at(0)};
    const auto replayed = replay_recording(from, lp, ro);
    for (const LaneReplay& l : replayed) {
      measure_miss_margins(e, l.lane, l.fillets, lp.lane(l.lane).inspection);
      measure_fragment_chances(e, l.lane, l.fillets, lp.lane(l.lane).inspection);
    }
  };
  // Every fragment's chance is measured (what recall the bone allows), so each run is
  // replayed, misses or none.
  margins(r.learned, rec);
  if (s.mo.bone_fillets > 0) {
    PartRun bones = s.more();
    bones.fillets = s.mo.bone_fillets, bones.seed = s.mo.seed + 10000;
    r.bones = run_bone_parts(bones, lc, margins);
  }
  const std::string report = s.learn_report();
  r.fragment_claims =
      claims_on_fragments(report_claims(report, lane), r.learned, s.mo.seed, r.bones);
  r.claims_measured = true;
  read_learning(s, lane, r);
}

MatrixRow run_variant(const fs::path& file, const fs::path& dir, const PlantConfig& plant,
                      const std::string& config, const MatrixOptions& mo) {
  MatrixRow r;
  const VariantRun v(file, dir);
  r.name = v.name, r.held_out = v.held_out;
  const VariantSteps s{v, config, mo};
  calibrate_and_process(s);
  if (mo.learn_fillets > 0) learn_and_process(s, r);
  // Evaluation against the recording's truth.
  const RecordingReader rec(s.at("rec"));
  const RecordingInfo& info = rec.info();
  const int lane = info.lanes.at(0);
  const LaneConfig lc = load_lane_calibration(plant, lane, v.cal);
  const fs::path ld = dir / "out" / ("lane" + std::to_string(lane));
  std::vector<float> rows[2] = {read_f32(ld / "stripe_cam0.f32", size_t(info.lines) * info.width),
                                read_f32(ld / "stripe_cam1.f32", size_t(info.lines) * info.width)};
  const auto t = read_f32(ld / "thickness.f32", size_t(info.lines) * info.xray_pixels);
  r.thickness = evaluate_lane(rec, lc, rows, t).thickness;
  const VariantTruth vt(rec, lc);
  r.cartilage = int(std::count_if(vt.fragments.begin(), vt.fragments.end(),
                                  [](const TruthFragment& f) { return f.kind == "cartilage"; }));
  add_lane(r.ours, vt.fragments, vt.fillets, read_records(ld.string(), ""), &vt.edges);
  add_lane(r.base, vt.fragments, vt.fillets, read_records(ld.string(), "baseline_"), &vt.edges);
  finish(r.ours);
  finish(r.base);
  if (r.learned_run) evaluate_learned(s, rec, lc, vt, r);
  drop_scans(dir, {"rec"}, mo);
  return r;
}

// The variants' files in name order, or those --only names, in its order.
std::vector<fs::path> variant_files(const Args& a, const fs::path& vdir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(vdir))
    if (e.path().extension() == ".yaml") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  if (a.has("only")) {
    std::vector<fs::path> keep;
    std::stringstream list(a.get("only", ""));
    std::string name;
    while (std::getline(list, name, ',')) {
      const auto it = std::find_if(files.begin(), files.end(),
                                   [&](const fs::path& p) { return p.stem() == name; });
      if (it == files.end()) fail("--only: no variant '", name, "' in ", vdir.string());
      keep.push_back(*it);
    }
    files = keep;
  }
  return files;
}

// The run's options from the command line, refused where out of range.
MatrixOptions matrix_options(const Args& a) {
  MatrixOptions mo;
  mo.fillets = int(a.integer("fillets", 60));
  mo.seed = a.integer("seed", 11);
  mo.keep = a.flag("keep-scans");
  mo.learn_fillets = int(a.integer("learn", 40));
  mo.check_fillets = int(a.integer("check", 20));
  mo.frr_fillets = int(a.integer("frr", 0));
  mo.frr_part = int(a.integer("frr-part", 60));
  mo.bone_fillets = int(a.integer("bones", 0));
  // Checked here, before hours of simulation, as learn checks it; passed on as written.
  a.number("confidence", 0.9, 0.5, 0.999);
  mo.confidence = a.get("confidence", "");
  a.number("tail-from", 0.5, 0, 0.95);
  mo.tail_from = a.get("tail-from", "");
  if (mo.frr_fillets < 0 || mo.frr_part < 1) fail("--frr must be >= 0 and --frr-part >= 1");
  if (mo.bone_fillets < 0) fail("--bones must be >= 0");
  if (mo.bone_fillets > 0 && mo.learn_fillets == 0)
    fail("--bones inspects with the learned thresholds: it needs --learn N > 0");
  if (mo.learn_fillets < 0 || mo.check_fillets < 1) fail("--learn must be >= 0 and --check >= 1");
  return mo;
}

}  // namespace

int cmd_eval_matrix(int argc, char** argv) {
  const Args a(argc, argv, 2, {"keep-scans", "dual-energy"},
               {"variants", "only", "fillets", "seed", "out", "config", "learn", "check", "frr",
                "frr-part", "bones", "confidence", "tail-from"});
  a.expect_positionals(
      0,
      "eval-matrix --out DIR [--variants DIR] [--only A,B] [--fillets N] "
      "[--seed S] [--learn N (0: none)] [--check N] [--frr N] [--frr-part N] [--bones N] "
      "[--confidence C] [--tail-from P (learn's)] [--keep-scans] "
      "[--dual-energy]");
  const PlantConfig plant = load_config(a.get("config", ""));
  const fs::path vdir = a.get(
      "variants", (fs::path(config_path(a.get("config", ""))).parent_path() / "variants").string());
  if (!fs::is_directory(vdir)) fail(vdir.string(), ": no such folder of plant variants");
  const std::vector<fs::path> files = variant_files(a, vdir);
  if (files.empty()) fail(vdir.string(), " holds no variant (*.yaml)");
  const MatrixOptions mo = matrix_options(a);
  const int fillets = mo.fillets;
  const fs::path out = a.require("out");
  if (a.flag("dual-energy")) {
    DualEnergyMatrixOptions d;
    d.fillets = mo.fillets, d.seed = mo.seed, d.learn_fillets = mo.learn_fillets;
    d.check_fillets = mo.check_fillets, d.frr_fillets = mo.frr_fillets, d.keep = mo.keep;
    d.bone_fillets = mo.bone_fillets, d.part = mo.frr_part;
    return run_dual_energy_matrix(files, out, config_path(a.get("config", "")), plant, d);
  }
  fs::create_directories(out);
  std::vector<MatrixRow> rows;
  std::string text;
  for (size_t k = 0; k < files.size(); ++k) {
    std::printf("[%zu/%zu] %s: calibrating from its own scenes, simulating %d fillets ...\n", k + 1,
                files.size(), files[k].stem().c_str(), fillets);
    std::fflush(stdout);
    const auto t0 = std::chrono::steady_clock::now();
    // A variant that fails is reported as failed and the others still run.
    try {
      rows.push_back(run_variant(files[k], out / files[k].stem(), plant,
                                 config_path(a.get("config", "")), mo));
    } catch (const std::exception& e) {
      MatrixRow r;
      r.name = files[k].stem().string(), r.failed = e.what();
      drop_scans(out / files[k].stem(),
                 {"rec", "pins", "blocks", "learn_rec", "check_rec", "frr_rec", "bone_rec"}, mo);
      rows.push_back(r);
      std::fprintf(stderr, "%s failed: %s\n", r.name.c_str(), e.what());
    }
    rows.back().minutes =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / 60;
    // Written after every variant, so that a long run's results are there as they come.
    text = matrix_text(rows, mo);
    std::ofstream(out / "matrix.txt") << text;
    std::ofstream(out / "matrix.json") << matrix_json(rows);
  }
  std::printf("\n%s", text.c_str());
  std::printf("written to %s/matrix.txt and matrix.json\n", out.c_str());
  return std::any_of(rows.begin(), rows.end(), [](const MatrixRow& r) { return !r.failed.empty(); })
             ? 2
             : 0;
}

}  // namespace rangex::cli
