// eval-matrix: detection on plants the project did not simulate. Each plant
// variant (config/variants/*.yaml) is calibrated from its own calibration scenes (the pin
// phantom for the fan beam and the detector's blur, blocks for the registration), its plant
// is simulated with its physics, K1/K2 are fitted on that plant's own recording, and the
// recording is replayed with that calibration and evaluated against its truth, beside the
// X-ray-only baseline. Held-out variants are reported apart. A benchmark (minutes per
// variant); the tests run a slice.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
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
#include "eval_steps.h"
#include "f32_file.h"
#include "learning_check.h"
#include "offline/acceptance.h"
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

struct Row {
  std::string name;
  bool held_out = false;
  ErrorStats thickness;
  DetectionEval ours, base;
  // With thresholds learned from the variant's own clean fillets (another seed), and what
  // the learning reported: ok, fillets it flagged as bone-like, its sensitivity claims
  // checked on a third set of clean fillets.
  DetectionEval learned;
  int learn_fillets = 0;
  bool learned_run = false, learn_ok = false;
  int learn_flagged = 0, claims = 0, claims_held = 0, claims_contradicted = 0;
  std::vector<std::string> claims_not_held;  // by band, as the check says them
  LearningCheck check;  // the fillets its learnings named, checked against the truth
  // The report's sentences checked on the check fillets, and their pieces pooled.
  int stated = 0, stated_held = 0, stated_found = 0, stated_injected = 0;
  // A large run of clean product alone with the learned thresholds: the false-reject rate
  // with an interval narrow enough to mean something.
  int frr_fillets = 0, frr_rejected = 0, frr_not_inspected = 0;
  int frr_fragments = 0;  // bone detections in the clean run
  // What the lane's drift monitor said over the clean run's passed fillets, in order:
  // whether the product's extremes follow the model learned from its learning fillets.
  RecordedDrift drift;
  std::string drift_sentence;
  std::vector<std::string> sensitivity;
  // More bony fillets with the learned thresholds (--bones): recall with a narrow interval.
  std::vector<BonePart> bones;
  // The report's sphere claims held against the plant's and the bone run's fragments.
  FragmentClaims fragment_claims;
  bool claims_measured = false;
  int cartilage = 0;  // pieces of cartilage or tendon in the plant's fillets (its truth)
  double minutes = 0;
  std::string failed;  // why the variant stopped (its log says more); empty when it ran
};

struct MatrixOptions {
  int fillets = 60;
  long seed = 11;
  bool keep = false;
  int learn_fillets = 40;  // 0: no learning
  int check_fillets = 20;
  int frr_fillets = 0;     // clean fillets inspected with the learned thresholds (0: none)
  int frr_part = 60;       // simulated, inspected and dropped this many at a time
  int bone_fillets = 0;    // more bony fillets inspected with the learned thresholds (0: none)
  std::string confidence;  // learn's --confidence ("": learn's default)
  std::string tail_from;   // learn's --tail-from ("": learn's default)
};

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
void learn_and_process(const VariantSteps& s, Row& r) {
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
std::vector<RecordSet> read_clean_runs(const fs::path& dir, int lane, Row& r) {
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
void read_learning(const VariantSteps& s, int lane, Row& r) {
  const std::string report = (s.v.dir / "learned.report" / "learn.json").string();
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
                      const VariantTruth& vt, Row& r) {
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
  const std::string report = (s.v.dir / "learned.report" / "learn.json").string();
  r.fragment_claims =
      claims_on_fragments(report_claims(report, lane), r.learned, s.mo.seed, r.bones);
  r.claims_measured = true;
  read_learning(s, lane, r);
}

Row run_variant(const fs::path& file, const fs::path& dir, const PlantConfig& plant,
                const std::string& config, const MatrixOptions& mo) {
  Row r;
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

std::string table(const std::vector<Row>& rows, bool held_out) {
  std::ostringstream os;
  char b[512];
  std::snprintf(b, sizeof b,
                "%-19s %7s %7s %6s | %8s %7s %7s %7s | %7s %6s %9s %6s %6s | %8s %7s\n", "variant",
                "thick", "bias", "resid", "recall", "needle", "edge", "posit.", "f.rej", "n.i.",
                "f.frag/f", "<1mm", "1-3mm", "xr:rec", "xr:frej");
  os << b;
  for (const Row& r : rows) {
    if (r.held_out != held_out || !r.failed.empty()) continue;
    const DetectionEval& e = r.ours;
    std::snprintf(b, sizeof b,
                  "%-19s %7.3f %+7.3f %6.1f | %7.1f%% %7s %7s %7.3f | %6.1f%% %6d %9.3f %6d %6d | "
                  "%7.1f%% %6.1f%%\n",
                  r.name.c_str(), r.thickness.mean_abs, r.thickness.bias, e.resid_std_dn,
                  100 * e.recall_calcified_2mm(), shape_recall(e, "needle").c_str(),
                  (std::to_string(e.found_edge) + "/" + std::to_string(e.total_edge)).c_str(),
                  e.position.stats().mean_abs, 100 * e.false_reject_rate(), e.not_inspected,
                  e.fillets ? double(e.false_fragments) / e.fillets : 0.0, e.false_by_edge[0],
                  e.false_by_edge[1], 100 * r.base.recall_calcified_2mm(),
                  100 * r.base.false_reject_rate());
    os << b;
  }
  return os.str();
}

std::string learned_table(const std::vector<Row>& rows, bool held_out) {
  std::ostringstream os;
  char b[512];
  std::snprintf(b, sizeof b, "%-19s %5s %4s | %13s %7s | %11s %9s %9s | %15s %8s | %6s %15s %s\n",
                "variant", "learn", "flag", "recall [95%]", "needle", "f.rej", "[95%]", "f.frag/f",
                "clean: f.rej", "[95%]", "bands", "stated (pieces)",
                "sensitivity (learning fillets)");
  os << b;
  for (const Row& r : rows) {
    if (r.held_out != held_out || !r.learned_run) continue;
    const DetectionEval& e = r.learned;
    int k = 0, n = 0;
    calcified_2mm(e, k, n);
    const std::string clean = r.frr_fillets ? std::to_string(r.frr_rejected) + "/" +
                                                  std::to_string(r.frr_fillets) + " (" +
                                                  std::to_string(r.frr_fragments) + " bone)"
                                            : "-";
    const std::string stated = std::to_string(r.stated_held) + "/" + std::to_string(r.stated) +
                               " (" + std::to_string(r.stated_found) + "/" +
                               std::to_string(r.stated_injected) + ")";
    std::snprintf(
        b, sizeof b,
        "%-19s %5s %4d | %5.1f%% %6s %7s | %4d/%-4d %10s %9.3f | %15s %8s | %2d/%-3d %15s %s\n",
        r.name.c_str(),
        !r.learn_ok    ? "FAIL"
        : r.check.kept ? "kept"
                       : "ok",
        r.check.named, n ? 100.0 * k / n : 0.0, interval(k, n).c_str(),
        shape_recall(e, "needle").c_str(), e.clean_rejected, e.clean_fillets,
        interval(e.clean_rejected, e.clean_fillets).c_str(),
        e.fillets ? double(e.false_fragments) / e.fillets : 0.0, clean.c_str(),
        interval(r.frr_rejected, r.frr_fillets).c_str(), r.claims_held, r.claims, stated.c_str(),
        r.sensitivity.empty() ? "-" : r.sensitivity.front().c_str());
    os << b;
  }
  return os.str();
}

// The misses of `e` as JSON objects, comma-separated; `seed` >= 0 names the bone run's part.
std::string missed_json(const DetectionEval& e, long seed) {
  std::ostringstream os;
  for (size_t q = 0; q < e.missed.size(); ++q) {
    const MissedFragment& m = e.missed[q];
    os << (q ? ", " : "") << "{";
    if (seed >= 0) os << "\"seed\": " << seed << ", ";
    os << "\"fillet\": " << m.fillet << ", \"shape\": \"" << m.shape
       << "\", \"size_mm\": " << m.size_mm << ", \"calcification\": " << m.calcification
       << ", \"volume_mm3\": " << m.volume_mm3 << ", \"meat_mm\": " << m.meat_mm
       << ", \"edge_mm\": " << m.edge_mm << ", \"found_at\": " << m.found_at
       << ", \"frr_at\": " << m.frr_at << ", \"margin_statistic\": \""
       << (m.margin_stat >= 0 ? statistic_name(m.margin_stat) : "every")
       << "\", \"chance\": " << m.chance.chance << ", \"response\": " << m.chance.response
       << ", \"chance_threshold\": " << m.chance.threshold << ", \"fillet_decision\": \""
       << m.fillet_decision << "\"}";
  }
  return os.str();
}

// What the calcified fragments >= 2 mm of the plant and the bone run allow at the learned
// thresholds (offline/fragment_chance.h): their chances summed, over `measured` of them.
double bone_allows(const Row& r, int& measured) {
  double sum = 0;
  measured = 0;
  auto add = [&](const DetectionEval& e) {
    int m = 0;
    const double mean = expected_recall(e, m);
    if (m > 0) sum += mean * m, measured += m;
  };
  add(r.learned);
  for (const BonePart& p : r.bones) add(p.eval);
  return sum;
}

// Each calcified fragment >= 2 mm whose chance was measured (offline/fragment_chance.h),
// with its part's seed (-1: the plant's).
std::string chances_json(const DetectionEval& e, long seed, bool& first) {
  std::ostringstream os;
  for (const JudgedFragment& j : e.judged) {
    const FragmentChance& c = j.chance;
    if (c.chance < 0) continue;
    os << (first ? "" : ", ") << "{\"seed\": " << seed << ", \"fillet\": " << j.fillet
       << ", \"size_mm\": " << j.size_mm << ", \"volume_mm3\": " << j.volume_mm3
       << ", \"calcification\": " << j.calcification << ", \"meat_mm\": " << j.meat_mm
       << ", \"found\": " << (j.found ? "true" : "false") << ", \"statistic\": \""
       << statistic_name(c.stat) << "\", \"response\": " << c.response
       << ", \"observed\": " << c.observed << ", \"threshold\": " << c.threshold
       << ", \"chance\": " << c.chance << "}";
    first = false;
  }
  return os.str();
}

// The bone run of each variant that had one: recall pooled with the plant's, by shape, the
// clean fillets among them rejected, detections of no bone, and its misses.
std::string bone_run_text(const std::vector<Row>& rows) {
  std::ostringstream os;
  char b[512];
  for (const Row& r : rows) {
    if (r.bones.empty()) continue;
    const BoneRunTotals t = pooled(r.bones);
    int k = 0, n = 0;
    calcified_2mm(r.learned, k, n);
    k += t.found, n += t.present;
    std::snprintf(b, sizeof b,
                  "%s%s: %d fillets: calcified >= 2 mm %d/%d; with the plant's %d/%d = %.1f %% "
                  "[%s %%]; clean fillets rejected %d/%d [%s %%]; detections of no bone %.3f a "
                  "fillet\n",
                  r.name.c_str(), r.held_out ? " (held out)" : "", t.fillets, t.found, t.present, k,
                  n, n ? 100.0 * k / n : 0.0, interval(k, n).c_str(), t.clean_rejected, t.clean,
                  interval(t.clean_rejected, t.clean).c_str(),
                  t.fillets ? double(t.false_fragments) / t.fillets : 0.0);
    os << b;
    // What a plant's customers would find: fillets holding such bone that passed.
    const int cf = t.calcified_fillets + r.learned.calcified_fillets,
              cp = t.calcified_passed + r.learned.calcified_passed;
    std::snprintf(b, sizeof b,
                  "  fillets holding calcified >= 2 mm passed down the line (plant and bone "
                  "run): %d of %d [%s %%]\n",
                  cp, cf, interval(cp, cf).c_str());
    os << b << "  by shape (bone run):";
    for (const auto& [shape, fp] : t.by_shape)
      os << " " << shape << " " << fp.first << "/" << fp.second;
    int measured = 0;
    const double sum = bone_allows(r, measured);
    if (measured > 0) {
      std::snprintf(b, sizeof b,
                    "\n  were each fragment's bone a sphere (one more injected where it lies, its "
                    "chance at the thresholds Phi(E - T)), their chances would sum to %.1f of "
                    "%d = %.1f %%",
                    sum, measured, 100 * sum / measured);
      os << b;
    }
    os << "\n" << prefixed(bone_run_missed_lines(r.bones), "  ");
  }
  return os.str();
}

// The run's fillets pooled: the plant's and its clean and bone runs, with the thresholds
// learned.
AcceptanceCounts acceptance_counts(const Row& r) {
  AcceptanceCounts c;
  const DetectionEval& e = r.learned;
  calcified_2mm(e, c.found, c.present);
  c.clean_rejected = e.clean_rejected + r.frr_rejected, c.clean = e.clean_fillets + r.frr_fillets;
  c.no_bone = e.false_fragments + r.frr_fragments, c.fillets = e.fillets + r.frr_fillets;
  auto shapes = e.by_shape;
  if (!r.bones.empty()) {
    const BoneRunTotals t = pooled(r.bones);
    c.found += t.found, c.present += t.present;
    c.clean_rejected += t.clean_rejected, c.clean += t.clean;
    c.no_bone += t.false_fragments, c.fillets += t.fillets;
    shapes.insert(shapes.end(), t.by_shape.begin(), t.by_shape.end());
  }
  for (const auto& [shape, fp] : shapes) {
    if (shape == "needle") c.needles += fp.second;
    if (shape == "rib") c.ribs += fp.second;
  }
  c.cartilage = r.cartilage;
  return c;
}

std::string acceptance_section(const std::vector<Row>& rows) {
  std::ostringstream os;
  for (const Row& r : rows) {
    if (!r.learned_run || !r.failed.empty()) continue;
    const AcceptanceCounts c = acceptance_counts(r);
    const Acceptance a = judge_acceptance(c);
    os << r.name << (r.held_out ? " (held out)" : "") << ": " << (a.met() ? "met" : "not met")
       << "\n"
       << prefixed(acceptance_text(c, a), "  ");
  }
  return os.str();
}

std::string json(const std::vector<Row>& rows) {
  std::ostringstream os;
  os << "{\"variants\": [";
  for (size_t i = 0; i < rows.size(); ++i) {
    const Row& r = rows[i];
    const DetectionEval& e = r.ours;
    if (!r.failed.empty()) {
      os << (i ? ",\n  " : "\n  ") << nlohmann::json{{"name", r.name}, {"failed", r.failed}}.dump();
      continue;
    }
    os << (i ? ",\n  " : "\n  ") << "{\"name\": \"" << r.name
       << "\", \"held_out\": " << (r.held_out ? "true" : "false")
       << ", \"thickness_mean_abs_mm\": " << r.thickness.mean_abs
       << ", \"thickness_bias_mm\": " << r.thickness.bias
       << ", \"residual_std_dn\": " << e.resid_std_dn
       << ", \"recall_calcified_ge_2mm\": " << e.recall_calcified_2mm() << ", \"recall_edge\": ["
       << e.found_edge << ", " << e.total_edge << "]"
       << ", \"recall_inner\": [" << e.found_inner << ", " << e.total_inner << "]"
       << ", \"recall_by_shape\": {";
    for (size_t k = 0; k < e.by_shape.size(); ++k)
      os << (k ? ", " : "") << "\"" << e.by_shape[k].first << "\": [" << e.by_shape[k].second.first
         << ", " << e.by_shape[k].second.second << "]";
    os << "}, \"false_reject_rate\": " << e.false_reject_rate()
       << ", \"clean_fillets\": " << e.clean_fillets << ", \"fillets\": " << e.fillets
       << ", \"not_inspected\": " << e.not_inspected
       << ", \"false_fragments\": " << e.false_fragments << ", \"false_fragments_by_edge\": ["
       << e.false_by_edge[0] << ", " << e.false_by_edge[1] << ", " << e.false_by_edge[2] << "]"
       << ", \"position_mean_mm\": " << e.position.stats().mean_abs
       << ", \"baseline_recall_calcified_ge_2mm\": " << r.base.recall_calcified_2mm()
       << ", \"baseline_false_reject_rate\": " << r.base.false_reject_rate()
       << ", \"minutes\": " << r.minutes;
    if (r.learned_run) {
      const DetectionEval& l = r.learned;
      int k = 0, n = 0;
      calcified_2mm(l, k, n);
      os << ", \"learned\": {\"ok\": " << (r.learn_ok ? "true" : "false")
         << ", \"learning_fillets\": " << r.learn_fillets << ", \"flagged\": " << r.learn_flagged
         << ", \"named\": " << r.check.named << ", \"kept_checked_clean\": " << r.check.kept
         << ", \"left_out_bony\": " << r.check.bony << ", \"recall_calcified_ge_2mm\": [" << k
         << ", " << n << "], \"recall_by_shape\": {";
      for (size_t q = 0; q < l.by_shape.size(); ++q)
        os << (q ? ", " : "") << "\"" << l.by_shape[q].first << "\": ["
           << l.by_shape[q].second.first << ", " << l.by_shape[q].second.second << "]";
      os << "}, \"false_rejects\": [" << l.clean_rejected << ", " << l.clean_fillets
         << "], \"not_inspected\": " << l.not_inspected
         << ", \"false_fragments\": " << l.false_fragments << ", \"fillets\": " << l.fillets
         << ", \"claims\": " << r.claims << ", \"claims_held\": " << r.claims_held
         << ", \"claims_contradicted\": " << r.claims_contradicted << ", \"stated\": " << r.stated
         << ", \"stated_held\": " << r.stated_held << ", \"stated_pieces\": [" << r.stated_found
         << ", " << r.stated_injected << "]"
         << ", \"clean_run\": {\"fillets\": " << r.frr_fillets
         << ", \"rejected\": " << r.frr_rejected << ", \"not_inspected\": " << r.frr_not_inspected
         << ", \"fragments\": " << r.frr_fragments << ", \"drift\": " << drift_json(r.drift) << "}"
         << ", \"sensitivity\": [";
      for (size_t q = 0; q < r.sensitivity.size(); ++q)
        os << (q ? ", " : "") << "\"" << r.sensitivity[q] << "\"";
      os << "], \"missed\": [" << missed_json(l, -1) << "]";
      if (r.claims_measured) os << ", \"claims_on_fragments\": " << claims_json(r.fragment_claims);
      {
        bool first = true;
        os << ", \"fragment_chances\": [" << chances_json(r.learned, -1, first);
        for (const BonePart& b : r.bones) os << chances_json(b.eval, b.seed, first);
        os << "]";
      }
      if (!r.bones.empty()) {
        const BoneRunTotals t = pooled(r.bones);
        os << ", \"bone_run\": {\"fillets\": " << t.fillets << ", \"recall_calcified_ge_2mm\": ["
           << t.found << ", " << t.present << "], \"recall_by_shape\": {";
        for (size_t q = 0; q < t.by_shape.size(); ++q)
          os << (q ? ", " : "") << "\"" << t.by_shape[q].first << "\": ["
             << t.by_shape[q].second.first << ", " << t.by_shape[q].second.second << "]";
        int measured = 0;
        const double allows = bone_allows(r, measured);
        os << "}, \"bone_allows\": [" << allows << ", " << measured << "]";
        os << ", \"calcified_fillets_passed\": [" << t.calcified_passed << ", "
           << t.calcified_fillets << "]";
        os << ", \"false_rejects\": [" << t.clean_rejected << ", " << t.clean
           << "], \"false_fragments\": " << t.false_fragments << ", \"missed\": [";
        bool first = true;
        for (const BonePart& b : r.bones)
          if (!b.eval.missed.empty())
            os << (first ? "" : ", ") << missed_json(b.eval, b.seed), first = false;
        os << "]}";
      }
      const AcceptanceCounts c = acceptance_counts(r);
      const Acceptance a = judge_acceptance(c);
      os << ", \"acceptance\": {\"met\": " << (a.met() ? "true" : "false")
         << ", \"false_rejects\": [" << c.clean_rejected << ", " << c.clean
         << "], \"false_reject_upper\": " << a.false_reject_ci.hi
         << ", \"false_rejects_met\": " << (a.false_rejects_met ? "true" : "false")
         << ", \"no_bone\": [" << c.no_bone << ", " << c.fillets
         << "], \"no_bone_met\": " << (a.no_bone_met ? "true" : "false")
         << ", \"recall_calcified_ge_2mm\": [" << c.found << ", " << c.present
         << "], \"recall_judged\": " << (a.recall_judged ? "true" : "false")
         << ", \"recall_met\": " << (a.recall_met ? "true" : "false")
         << ", \"recall_exempt\": " << nlohmann::json(a.recall_exempt).dump()
         << ", \"needles\": " << c.needles << ", \"ribs\": " << c.ribs
         << ", \"cartilage\": " << c.cartilage << "}";
      os << "}";
    }
    os << "}";
  }
  os << "\n]}\n";
  return os.str();
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

// The matrix's report over the variants run so far.
std::string matrix_text(const std::vector<Row>& rows, const MatrixOptions& mo) {
  const int fillets = mo.fillets;
  const long seed = mo.seed;
  std::ostringstream os;
  os << "plant variants, each calibrated from its own scenes (" << fillets << " fillets each, seed "
     << seed << "):\n"
     << "thick/bias: thickness mean |error| and bias, mm; resid: how rough the plant is, the "
        "residual I - P's standard deviation in DN (the dissertation's real fillets: 29.6); "
        "recall: calcified fragments >= 2 mm;"
        " needle, edge: the same for needles and within 3 mm of the edge or on meat under 6 "
        "mm (found/present); posit.: position error, mm; f.rej: clean fillets rejected; n.i.: "
        "fillets not inspected; f.frag/f: detections matching no bone per fillet, <1mm / "
        "1-3mm of them from the meat's edge; xr: the X-ray-only baseline\n\n"
     << table(rows, false);
  if (std::any_of(rows.begin(), rows.end(), [](const Row& r) { return r.held_out; }))
    os << "\nheld out (never tuned on):\n" << table(rows, true);
  if (mo.learn_fillets > 0) {
    os << "\nwith thresholds learned from " << mo.learn_fillets
       << " clean fillets of each variant (another seed; claims checked on " << mo.check_fillets
       << " more): recall of calcified >= 2 mm with its 95 % interval; f.rej: clean fillets "
          "rejected with the 95 % interval in %; bands: sensitivity claims by thickness band "
          "held on the check fillets; stated: the report's sentences held there (their pieces "
          "found); flag: fillets the learning named as bone-like, each checked against the "
          "truth as a plant checks them by hand (kept: found clean and learned again with "
          "them, learn --keep; bony ones left out)\n\n"
       << learned_table(rows, false);
    if (std::any_of(rows.begin(), rows.end(), [](const Row& r) { return r.held_out; }))
      os << "\nheld out (never tuned on):\n" << learned_table(rows, true);
    if (std::any_of(rows.begin(), rows.end(),
                    [](const Row& r) { return !r.claims_not_held.empty(); })) {
      os << "\nclaims by band not held on the check fillets (a band's claim rests on 10-40 "
            "pieces there, which fall one or two short of its rate by chance about as often "
            "as not; contradicted: so few found in under 5 % of checks of a true claim):\n";
      for (const Row& r : rows)
        if (!r.claims_not_held.empty()) {
          os << r.name << ": " << r.claims_not_held.size() << " of " << r.claims << " not held, "
             << r.claims_contradicted << " contradicted\n";
          for (const std::string& t : r.claims_not_held) os << "  " << t << "\n";
        }
    }
    if (std::any_of(rows.begin(), rows.end(),
                    [](const Row& r) { return !r.drift_sentence.empty(); })) {
      os << "\nthe lane's drift monitor over the clean run (its passed fillets in order; "
            "a warning when the last 200 imply more than twice the target):\n";
      for (const Row& r : rows)
        if (!r.drift_sentence.empty())
          os << r.name << ":\n" << prefixed(r.drift_sentence, "  ") << "\n";
    }
    os << "\nwhere the learned thresholds missed calcified fragments >= 2 mm:\n";
    for (const Row& r : rows)
      if (r.learned_run)
        os << r.name << ": " << missed_summary(r.learned) << "\n"
           << prefixed(missed_lines(r.learned), "  ");
    if (mo.bone_fillets > 0)
      os << "\nthe bone run: " << mo.bone_fillets
         << " more fillets of each variant's plant, bones and all (seeds " << seed + 10000
         << ", +100 a part of " << mo.frr_part
         << "), inspected with the learned thresholds and judged against their truth; the "
            "interval is Wilson's 95 %, pooled with the plant's fragments:\n"
         << bone_run_text(rows);
    os << "\nthe report's sphere claims on each variant's own fragments (the plant's"
       << (mo.bone_fillets > 0 ? " and the bone run's" : "")
       << "): a compact fragment is covered where the claim for its band of meat is a sphere "
          "holding no more bone than it (volume x its attenuation over the meat, against the "
          "test piece's); the claim says 95 %:\n";
    for (const Row& r : rows)
      if (r.claims_measured) os << claims_text(r.name, r.fragment_claims);
    os << "\nagainst the acceptance targets, every fillet of this run pooled: the plant's, "
          "the clean run's and the bone run's, with the learned thresholds; Wilson's 95 % "
          "intervals. Recall is judged on plants without needles, rib plates or cartilage, "
          "and reported on the others:\n"
       << acceptance_section(rows);
  }
  for (const Row& r : rows)
    if (!r.failed.empty()) os << "\nfailed: " << r.name << ": " << r.failed << "\n";
  return os.str();
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
  std::vector<Row> rows;
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
      Row r;
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
    std::ofstream(out / "matrix.json") << json(rows);
  }
  std::printf("\n%s", text.c_str());
  std::printf("written to %s/matrix.txt and matrix.json\n", out.c_str());
  return std::any_of(rows.begin(), rows.end(), [](const Row& r) { return !r.failed.empty(); }) ? 2
                                                                                               : 0;
}

}  // namespace rangex::cli
