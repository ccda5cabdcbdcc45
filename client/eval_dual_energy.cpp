// eval-matrix --dual-energy: each plant variant's lane with a sandwich detector, inspected
// in one run five ways on the same fillets (docs/dual-energy.md):
// - one energy, as rangex did (the low line with the laser's thickness);
// - dual energy without the laser (a two-material decomposition: a dual-energy machine
//   alone);
// - dual energy with the laser (lean, fat and bone);
// - dual energy with the laser and one energy together (their z images summed);
// - the X-ray-only baseline (the low line).
// Each of the first four learns its thresholds from the variant's own clean fillets (the
// same ones) and is checked on the same recording and the same clean run; the baseline runs
// with its fixed thresholds. The lane is calibrated from its own scenes, its dual-energy
// calibration from its own step-wedge scan.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "calib/lane_calibration_file.h"
#include "core/error.h"
#include "core/text_file.h"
#include "eval_bone_run.h"
#include "eval_steps.h"
#include "learning_check.h"
#include "offline/fillet_records.h"

namespace fs = std::filesystem;

namespace rangex::cli {

namespace {

constexpr int kMethods = 4;
const char* const kMethodKeys[kMethods] = {"low_line", "no_laser", "laser", "laser_and_low_line"};
const char* const kMethodNames[kMethods] = {"one energy + laser", "dual energy, no laser",
                                            "dual energy + laser", "dual + one energy, laser"};
constexpr int kLaser = 2;  // the method: its misses are listed

struct MethodRun {
  DetectionEval eval;
  bool learn_ok = false;
  int frr_fillets = 0, frr_rejected = 0, frr_fragments = 0;
  std::vector<BonePart> bones;  // the bone run (--bones), judged part by part
};

struct DualEnergyRow {
  std::string name;
  bool held_out = false;
  MethodRun m[kMethods];
  DetectionEval base;  // X-ray only, fixed thresholds
  std::vector<BonePart> base_bones;
};

// The plant configuration with every lane on two energies, inspecting as `method` says.
void write_method_config(const std::string& config, const std::string& method,
                         const fs::path& out) {
  YAML::Node root = YAML::LoadFile(config);
  root["lane_defaults"]["xray"]["energies"] = 2;
  root["lane_defaults"]["inspection"]["dual_energy"] = method;
  for (YAML::Node ln : root["lanes"]) {
    if (ln["xray"]) ln["xray"]["energies"] = 2;
    if (ln["inspection"]) ln["inspection"]["dual_energy"] = method;
  }
  YAML::Emitter e;
  e << root;
  std::ofstream(out) << "# eval-matrix --dual-energy: " << config << " on two energies, " << method
                     << "\n"
                     << e.c_str() << "\n";
}

DualEnergyRow run_variant(const fs::path& file, const fs::path& dir, const fs::path& configs,
                          const PlantConfig& plant, const DualEnergyMatrixOptions& mo) {
  DualEnergyRow r;
  const VariantRun v(file, dir);
  r.name = v.name, r.held_out = v.held_out;
  const std::string &log = v.log, &V = v.physics, &cal = v.cal;
  auto at = [&](const std::string& name) { return v.at(name); };
  const std::string base_config = (configs / "plant-laser.yaml").string();
  auto step = [&](std::vector<std::string> args, const std::string& config) {
    args.insert(args.end(), {"--config", config});
    run_step(log, std::move(args));
  };
  // The lane's own calibration: fan beam and blur from its pins, registration from its
  // blocks, the dual-energy fit from its wedge, K1/K2 from its own recording.
  step({"calib", "simulate", "pins", at("pins"), "--physics", V}, base_config);
  step({"calib", "simulate", "blocks", at("blocks"), "--physics", V}, base_config);
  step({"calib", "simulate", "dual-energy", at("wedge"), "--seed", std::to_string(mo.seed)},
       base_config);
  step({"calib", "xray", at("pins"), "--out", cal}, base_config);
  step({"calib", "registration", at("blocks"), "--calibration", cal}, base_config);
  step({"calib", "dual-energy", at("wedge"), "--calibration", cal}, base_config);
  auto simulate = [&](const char* name, int fillets, long seed, bool clean) {
    std::vector<std::string> a = {"simulate",
                                  "--out",
                                  at(name),
                                  "--lanes",
                                  "1",
                                  "--fillets",
                                  std::to_string(fillets),
                                  "--seed",
                                  std::to_string(seed),
                                  "--physics",
                                  V};
    if (clean) a.push_back("--clean");
    step(a, base_config);
  };
  simulate("rec", mo.fillets, mo.seed, false);
  simulate("learn_rec", mo.learn_fillets, mo.seed + 1000, true);
  simulate("check_rec", mo.check_fillets, mo.seed + 2000, true);
  if (mo.frr_fillets > 0) simulate("frr_rec", mo.frr_fillets, mo.seed + 3000, true);
  step({"calib", "scatter", at("rec"), "--calibration", cal}, base_config);

  const RecordingReader rec(at("rec"));
  const LaneConfig lc = load_lane_calibration(plant, rec.info().lanes.at(0), cal);
  const VariantTruth vt(rec, lc);
  const std::string lane_dir = "lane" + std::to_string(lc.id);
  for (int k = 0; k < kMethods; ++k) {
    const std::string key = kMethodKeys[k];
    const std::string cfg = (configs / ("plant-" + key + ".yaml")).string();
    const std::string learned = at("learned_" + key + ".yaml");
    learn_as_a_plant_would(log, at("learn_rec"), learned,
                           {"--calibration", cal, "--check", at("check_rec"), "--version",
                            "matrix-" + r.name + "-" + key, "--config", cfg});
    run_step(log, {"process", at("rec"), "--out", at("out_" + key), "--images", "none",
                   "--calibration", cal, "--config", learned});
    MethodRun& m = r.m[k];
    const fs::path od = dir / ("out_" + key) / lane_dir;
    add_lane(m.eval, vt.fragments, vt.fillets, read_records(od.string(), ""), &vt.edges);
    finish(m.eval);
    if (k == kLaser) {
      add_lane(r.base, vt.fragments, vt.fillets, read_records(od.string(), "baseline_"), &vt.edges);
      finish(r.base);
    }
    const auto j = YAML::LoadFile(at("learned_" + key + ".report/learn.json"));
    for (const auto& l : j["lanes"]) m.learn_ok = l["ok"].as<bool>();
    if (mo.frr_fillets > 0) {
      run_step(log, {"process", at("frr_rec"), "--out", at("frr_" + key), "--images", "none",
                     "--calibration", cal, "--config", learned});
      const RecordSet clean = read_records((dir / ("frr_" + key) / lane_dir).string(), "");
      m.frr_fillets = int(clean.fillets.size());
      for (const auto& f : clean.fillets) m.frr_rejected += f.decision != "pass";
      for (const auto& f : clean.fragments) m.frr_fragments += f.kind == "bone";
    }
  }
  // The scans are judged and learned from: dropped before the bone run's (130 MB a fillet).
  if (!mo.keep)
    for (const char* d : {"rec", "pins", "blocks", "wedge", "learn_rec", "check_rec", "frr_rec"})
      fs::remove_all(dir / d);
  // The bone run: more bony fillets (seeds seed + 10000, + 100 a part, as the one-energy
  // matrix's), each part simulated once and inspected by every method with the thresholds
  // it learned, so that the methods' recall is compared on the same fragments.
  if (mo.bone_fillets > 0) {
    PartRun o;
    o.dir = dir, o.log = log, o.physics = V, o.cal = cal, o.config = base_config;
    o.rec = "bone_rec", o.out = "out_bones", o.fillets = mo.bone_fillets, o.part = mo.part;
    o.seed = mo.seed + 10000, o.clean = false, o.keep = mo.keep;
    run_in_parts(o, [&](int, long seed, const std::string& rec_dir, const std::string& out) {
      const RecordingReader brec(rec_dir);
      const VariantTruth bt(brec, lc);
      for (int k = 0; k < kMethods; ++k) {
        const std::string key = kMethodKeys[k], od = out + "_" + key;
        run_step(log, {"process", rec_dir, "--out", od, "--images", "none", "--calibration", cal,
                       "--config", at("learned_" + key + ".yaml")});
        const std::string ld = (fs::path(od) / lane_dir).string();
        auto judge = [&](std::vector<BonePart>& parts, const char* prefix) {
          BonePart& p = parts.emplace_back();
          p.seed = seed;
          add_lane(p.eval, bt.fragments, bt.fillets, read_records(ld, prefix), &bt.edges);
          finish(p.eval);
        };
        judge(r.m[k].bones, "");
        if (k == kLaser) judge(r.base_bones, "baseline_");
      }
    });
  }
  return r;
}

std::string pct(int k, int n) {
  char b[48];
  if (n == 0) return "-";
  std::snprintf(b, sizeof b, "%d/%d %5.1f%% [%s]", k, n, 100.0 * k / n, interval(k, n).c_str());
  return b;
}

// A method's line: recall of calcified >= 2 mm, weakly calcified >= 2 mm, needles, false
// rejects of the recording's clean fillets, false detections per fillet, the clean run.
std::string method_line(const std::string& variant, const std::string& method,
                        const DetectionEval& e, const MethodRun* m) {
  int k = 0, n = 0, wk = 0, wn = 0;
  calcified_2mm(e, k, n);
  for (int s = 1; s < kSizeBins; ++s) wk += e.found[s][0], wn += e.total[s][0];
  char b[640];
  std::snprintf(b, sizeof b, "%-14s %-24s | %-26s | %-24s | %7s | %-24s | %6.3f | %-24s %6s\n",
                variant.c_str(), method.c_str(), pct(k, n).c_str(), pct(wk, wn).c_str(),
                shape_recall(e, "needle").c_str(), pct(e.clean_rejected, e.clean_fillets).c_str(),
                e.fillets ? double(e.false_fragments) / e.fillets : 0.0,
                m && m->frr_fillets ? pct(m->frr_rejected, m->frr_fillets).c_str() : "-",
                m ? (m->learn_ok ? "ok" : "FAIL") : "fixed");
  return b;
}

std::string size_line(const std::string& variant, const std::string& method,
                      const DetectionEval& e) {
  std::string out = variant;
  out.resize(std::max<size_t>(15, out.size() + 1), ' ');
  std::string mm = method;
  mm.resize(24, ' ');
  out += mm + " |";
  for (int c = 1; c >= 0; --c)
    for (int s = 0; s < kSizeBins; ++s) {
      char b[32];
      std::snprintf(b, sizeof b, " %3d/%-3d", e.found[s][c], e.total[s][c]);
      out += b;
      if (s == kSizeBins - 1) out += " |";
    }
  return out + "\n";
}

// A method's recall of calcified fragments >= 2 mm over the recording and the bone run
// pooled, the bone run's clean fillets rejected, its detections of no bone a fillet, needles.
std::string bone_line(const std::string& variant, const std::string& method,
                      const DetectionEval& plant, const std::vector<BonePart>& bones) {
  int k = 0, n = 0;
  calcified_2mm(plant, k, n);
  const BoneRunTotals t = pooled(bones);
  char b[512];
  std::snprintf(b, sizeof b, "%-14s %-24s | %-8s | %-26s | %-24s | %6.3f | %7s\n", variant.c_str(),
                method.c_str(), (std::to_string(k) + "/" + std::to_string(n)).c_str(),
                pct(k + t.found, n + t.present).c_str(), pct(t.clean_rejected, t.clean).c_str(),
                t.fillets ? double(t.false_fragments) / t.fillets : 0.0,
                shape_recall(t.by_shape, "needle").c_str());
  return b;
}

// The bone run of each variant that had one (--bones), by method, and the misses of one
// energy and of dual energy with the laser, each named by its part's seed.
std::string bone_run_text(const std::vector<DualEnergyRow>& rows,
                          const DualEnergyMatrixOptions& mo) {
  if (mo.bone_fillets == 0) return "";
  std::ostringstream os;
  os << "\nthe bone run: " << mo.bone_fillets << " more fillets, bones and all (seeds "
     << mo.seed + 10000 << ", +100 a part of " << mo.part
     << "), inspected by each method with the thresholds it learned; recall: calcified >= 2 "
        "mm, the recording's and the bone run's pooled [95 %]; needles: the bone run's\n";
  char h[512];
  std::snprintf(h, sizeof h, "%-14s %-24s | %-8s | %-26s | %-24s | %6s | %7s\n", "variant",
                "method", "record.", "recall >= 2 mm, pooled", "bone run: clean rejected",
                "f.det/f", "needle");
  os << h;
  for (const DualEnergyRow& r : rows) {
    for (int k = 0; k < kMethods; ++k)
      os << bone_line(r.name, kMethodNames[k], r.m[k].eval, r.m[k].bones);
    os << bone_line(r.name, "X-ray only (fixed)", r.base, r.base_bones);
  }
  for (const DualEnergyRow& r : rows)
    for (int k : {0, kLaser}) {
      const std::string missed = bone_run_missed_lines(r.m[k].bones);
      os << "\n"
         << r.name << ", the bone run's misses, " << kMethodNames[k] << ":"
         << (missed.empty() ? " none\n" : "\n" + missed);
    }
  return os.str();
}

std::string report(const std::vector<DualEnergyRow>& rows, const DualEnergyMatrixOptions& mo) {
  std::ostringstream os;
  os << "dual energy side by side: each variant's lane on a sandwich detector, " << mo.fillets
     << " fillets (seed " << mo.seed << "); each method learned its thresholds from the same "
     << mo.learn_fillets << " clean fillets; the clean run: " << mo.frr_fillets
     << " more clean fillets. [95 %] Wilson intervals.\n"
     << "recall: calcified (>= 0.6) fragments >= 2 mm; weak: calcification < 0.6, >= 2 mm; "
        "f.rej: the recording's clean fillets rejected; f.det/f: detections matching no bone "
        "per fillet\n\n";
  char h[640];
  std::snprintf(h, sizeof h, "%-14s %-24s | %-26s | %-24s | %7s | %-24s | %6s | %-24s %6s\n",
                "variant", "method", "recall >= 2 mm", "weak >= 2 mm", "needle", "f.rej", "f.det/f",
                "clean run: f.rej", "learn");
  for (int held = 0; held < 2; ++held) {
    if (held) os << "\nheld out (written once, never tuned on):\n";
    os << h;
    for (const DualEnergyRow& r : rows) {
      if (r.held_out != bool(held)) continue;
      for (int k = 0; k < kMethods; ++k)
        os << method_line(r.name, kMethodNames[k], r.m[k].eval, &r.m[k]);
      os << method_line(r.name, "X-ray only (fixed)", r.base, nullptr);
    }
  }
  // Pooled over every variant: what the bar is measured on.
  os << "\npooled over the variants above:\n" << h;
  for (int k = 0; k <= kMethods; ++k) {
    DetectionEval all;
    MethodRun run;
    for (const DualEnergyRow& r : rows) {
      const DetectionEval& e = k < kMethods ? r.m[k].eval : r.base;
      for (int s = 0; s < kSizeBins; ++s)
        for (int c = 0; c < kCalcBins; ++c)
          all.found[s][c] += e.found[s][c], all.total[s][c] += e.total[s][c];
      all.clean_rejected += e.clean_rejected, all.clean_fillets += e.clean_fillets;
      all.fillets += e.fillets, all.false_fragments += e.false_fragments;
      for (const auto& [shape, fb] : e.by_shape) {
        auto it = std::find_if(all.by_shape.begin(), all.by_shape.end(),
                               [&](const auto& q) { return q.first == shape; });
        if (it == all.by_shape.end()) it = all.by_shape.insert(all.by_shape.end(), {shape, {0, 0}});
        it->second.first += fb.first, it->second.second += fb.second;
      }
      if (k < kMethods) {
        run.frr_fillets += r.m[k].frr_fillets, run.frr_rejected += r.m[k].frr_rejected;
        run.learn_ok = true;
      }
    }
    os << method_line("all", k < kMethods ? kMethodNames[k] : "X-ray only (fixed)", all,
                      k < kMethods ? &run : nullptr);
  }
  os << "\nrecall by size, found/present: calcified 1-2 2-3 3-5 5-10 mm | weakly calcified "
        "1-2 2-3 3-5 5-10 mm\n";
  for (const DualEnergyRow& r : rows) {
    for (int k = 0; k < kMethods; ++k) os << size_line(r.name, kMethodNames[k], r.m[k].eval);
    os << size_line(r.name, "X-ray only (fixed)", r.base);
  }
  os << bone_run_text(rows, mo);
  os << "\nwhere dual energy with the laser missed calcified fragments >= 2 mm:\n";
  for (const DualEnergyRow& r : rows)
    os << r.name << ": " << missed_summary(r.m[kLaser].eval) << "\n"
       << missed_lines(r.m[kLaser].eval);
  return os.str();
}

}  // namespace

int run_dual_energy_matrix(const std::vector<fs::path>& files, const fs::path& out,
                           const std::string& config, const PlantConfig& plant,
                           const DualEnergyMatrixOptions& mo) {
  if (mo.learn_fillets < 30)
    fail("--dual-energy compares learned thresholds: --learn must be at least 30 (got ",
         mo.learn_fillets, ")");
  fs::create_directories(out);
  for (const char* m : kMethodKeys)
    write_method_config(config, m, out / (std::string("plant-") + m + ".yaml"));
  std::vector<DualEnergyRow> rows;
  std::string text;
  for (size_t k = 0; k < files.size(); ++k) {
    std::printf("[%zu/%zu] %s: calibrating, simulating, learning and inspecting 5 ways ...\n",
                k + 1, files.size(), files[k].stem().c_str());
    std::fflush(stdout);
    rows.push_back(run_variant(files[k], out / files[k].stem(), out, plant, mo));
    text = report(rows, mo);
    std::ofstream(out / "dual_energy.txt") << text;
  }
  std::printf("\n%s", text.c_str());
  std::printf("written to %s/dual_energy.txt\n", out.c_str());
  return 0;
}

}  // namespace rangex::cli
