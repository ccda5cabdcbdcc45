// simulate, extract, process, eval: the offline commands over recordings.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <thread>

#include "args.h"
#include "backend_args.h"
#include "calib/lane_calibration_file.h"
#include "commands.h"
#include "core/error.h"
#include "core/json_text.h"
#include "core/png_io.h"
#include "f32_file.h"
#include "offline/detection_eval.h"
#include "offline/evaluation.h"
#include "offline/fillet_records.h"
#include "offline/plant_run.h"
#include "offline/recorded_drift.h"
#include "offline/replay.h"
#include "pipeline/fillet_images.h"
#include "pipeline/recorded_stripes.h"
#include "progress_bar.h"
#include "sim/perturbed_rig.h"
#include "sim/plant_simulator.h"

namespace fs = std::filesystem;

namespace rangex::cli {

namespace {

void write_f32(const fs::path& p, const std::vector<float>& v) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * sizeof(float)));
  if (!out) fail(p.string(), ": write failed");
}

}  // namespace

int cmd_simulate(int argc, char** argv) {
  const Args a(argc, argv, 2, {"clean"},
               {"lanes", "fillets", "seed", "out", "config", "rig-seed", "physics"});
  a.expect_positionals(0,
                       "simulate --out DIR [--lanes N] [--fillets M] [--seed S] [--rig-seed R] "
                       "[--physics F] [--clean]");
  PlantConfig plant = load_config(a.get("config", ""));
  // A plant whose rigs differ from plant.yaml (as `calib simulate --rig-seed` draws them).
  if (a.has("rig-seed"))
    for (auto& l : plant.lanes)
      l = sim::perturbed_rig(l, (unsigned long)a.integer("rig-seed", 1)).lane;
  sim::SimulationParams p;
  p.lanes = int(a.integer("lanes", long(plant.lanes.size())));
  p.scene.fillets = int(a.integer("fillets", 5));
  p.seed = uint64_t(a.integer("seed", 1));
  // A plant rendered with other physics (config/variants/*.yaml).
  if (a.has("physics")) p.physics = sim::load_plant_physics(a.require("physics"));
  // A learning run of clean product: no bone (cartilage and everything else as the plant has).
  if (a.flag("clean")) p.physics.bones.probability = 0;
  const std::string out = a.require("out");
  ProgressBar bar("simulate");
  sim::simulate_recording(plant, p, out, [&](int64_t d, int64_t t) { bar.update(d, t); });
  const RecordingReader rec(out);
  std::printf("wrote %s: %zu lanes x %lld lines, %d fillets per lane, seed %llu, physics %s\n",
              out.c_str(), rec.info().lanes.size(), (long long)rec.info().lines, p.scene.fillets,
              (unsigned long long)p.seed, p.physics.name.c_str());
  return 0;
}

int cmd_extract(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, {"lane", "camera", "method", "out", "config"});
  a.expect_positionals(1, "extract DIR --lane L --camera C [--method NAME] --out peaks.csv");
  const RecordingReader rec(a.positional(0, "recording folder"));
  const int lane = int(a.integer("lane", 0));
  const int camera = int(a.integer("camera", 0));
  if (camera != 0 && camera != 1) fail("--camera must be 0 or 1 (got ", camera, ")");
  LaneConfig lc = load_config(a.get("config", "")).lane(lane);
  if (a.has("method")) lc.stripe.method = parse_stripe_method(a.get("method", ""));
  if (lc.frame_width != rec.info().width || lc.frame_height != rec.info().height)
    fail("lane ", lane, ": recording frames are ", rec.info().width, "x", rec.info().height,
         " but the plant configuration says ", lc.frame_width, "x", lc.frame_height);
  const StripeSlot slot{lc.stripe, lc.cameras[camera].scatter};
  const std::string out_path = a.require("out");
  std::ofstream out(out_path);
  if (!out) fail(out_path, ": cannot create");
  out << "frame,column,row\n";
  const int W = rec.info().width;
  ProgressBar bar("extract");
  char buf[64];
  for_each_recorded_stripe_batch(
      rec, lane, camera, slot, [&](int64_t n0, int count, const StripeOutput& so) {
        for (int k = 0; k < count; ++k)
          for (int c = 0; c < W; ++c) {
            const size_t o = size_t(k) * W + c;
            if (so.valid[o])
              std::snprintf(buf, sizeof buf, "%lld,%d,%.4f\n", (long long)(n0 + k), c, so.row[o]);
            else
              std::snprintf(buf, sizeof buf, "%lld,%d,\n", (long long)(n0 + k), c);
            out << buf;
          }
        bar.update(n0 + count, rec.info().lines);
      });
  if (!out) fail(out_path, ": write failed");
  return 0;
}

namespace {

// Which fillets get their images written.
enum class Images { kNone, kRejects, kAll };
Images parse_images(const std::string& v) {
  if (v == "none") return Images::kNone;
  if (v == "rejects") return Images::kRejects;
  if (v == "all") return Images::kAll;
  fail("--images must be none, rejects or all (got '", v, "')");
}

void maybe_write_images(const fs::path& lane_dir, const InspectedFillet& f, Images which) {
  if (which == Images::kNone || f.image.mask.empty()) return;
  if (which == Images::kRejects && f.result.decision == Decision::kPass) return;
  char name[48];
  std::snprintf(name, sizeof name, "fillet_%05lld", (long long)f.result.id);
  write_fillet_images((lane_dir / name).string(), f.image, f.result);
}

void write_lane_records(const fs::path& ld, const RecordSet& ours, const RecordSet& baseline) {
  write_records(ld.string(), "", ours);
  write_records(ld.string(), "baseline_", baseline);
  std::ofstream(ld / "fillets.json") << fillets_json(ours);
}

int count_decision(const RecordSet& s, const char* d) {
  int n = 0;
  for (const auto& f : s.fillets) n += f.decision == d;
  return n;
}

// Detection figures of a processed output folder against truth folders per lane.
std::string evaluate_output(const std::vector<int>& lanes, const fs::path& out,
                            const std::function<fs::path(int)>& truth_dir, int bits, bool json,
                            const std::vector<LaneEvaluation>& accuracy) {
  DetectionEval ours, base;
  for (int lane : lanes) {
    const fs::path ld = out / ("lane" + std::to_string(lane));
    const fs::path td = truth_dir(lane);
    auto text = [&](const char* name) {
      std::ifstream in(td / name);
      if (!in) fail((td / name).string(), " is missing: no truth to evaluate against");
      std::stringstream ss;
      ss << in.rdbuf();
      return ss.str();
    };
    const auto frags = parse_truth_fragments(text("fragments.csv"), lane);
    const auto fillets = parse_truth_fillets(text("fillets.csv"), lane);
    add_lane(ours, frags, fillets, read_records(ld.string(), ""));
    add_lane(base, frags, fillets, read_records(ld.string(), "baseline_"));
  }
  finish(ours);
  finish(base);
  if (json)
    return "{\"line_accuracy\": " + evaluations_json(accuracy) +
           ", \"detection\": " + detection_json(ours, base, bits) + "}\n";
  return evaluations_table(accuracy) + "\n" + detection_table(ours, base, bits);
}

int process_simulated(const Args& a, const PlantConfig& plant) {
  sim::SimulationParams p;
  p.lanes = int(a.integer("lanes", long(plant.lanes.size())));
  p.scene.fillets = int(a.integer("fillets", 125));
  p.seed = uint64_t(a.integer("seed", 1));
  if (a.has("physics")) p.physics = sim::load_plant_physics(a.require("physics"));
  const fs::path out = a.require("out");
  const Images images = parse_images(a.get("images", "rejects"));
  fs::create_directories(out);
  PlantRunOptions opt;
  opt.backend = backend_request(a, plant.backend);
  opt.on_fillet = [&](const InspectedFillet& f) {
    maybe_write_images(out / ("lane" + std::to_string(f.result.lane)), f, images);
  };
  ProgressBar bar("plant");
  BackendInfo backend;
  const auto lanes = run_simulated_plant(
      plant, p, opt, [&](int64_t d, int64_t t) { bar.update(d, t); }, &backend);
  std::printf("line stages on %s: %s (%s)\n", backend.name.c_str(), backend.device.c_str(),
              backend.driver.c_str());
  std::vector<int> ids;
  std::vector<LaneEvaluation> acc;
  for (const PlantRunLane& l : lanes) {
    const fs::path ld = out / ("lane" + std::to_string(l.lane));
    fs::create_directories(ld / "truth");
    write_lane_records(ld, l.ours, l.baseline);
    std::ofstream(ld / "truth" / "fragments.csv") << l.truth_fragments_csv;
    std::ofstream(ld / "truth" / "fillets.csv") << l.truth_fillets_csv;
    write_line_accuracy((ld / "line_accuracy.csv").string(), l.accuracy);
    ids.push_back(l.lane);
    acc.push_back(l.accuracy);
    std::printf(
        "lane %d: %lld lines, %zu fillets (%d pass, %d reject, %d not inspected), "
        "pipeline %.0f lines/s, inspection %.1f ms/fillet\n",
        l.lane, (long long)l.lines, l.ours.fillets.size(), count_decision(l.ours, "pass"),
        count_decision(l.ours, "reject"), count_decision(l.ours, "not_inspected"),
        l.pipeline_s > 0 ? double(l.lines) / l.pipeline_s : 0.0,
        l.ours.fillets.empty() ? 0.0 : 1e3 * l.inspection_s / double(l.ours.fillets.size()));
  }
  std::ofstream(out / "simulation.yaml")
      << "lanes: " << p.lanes << "\nfillets_per_lane: " << p.scene.fillets << "\nseed: " << p.seed
      << "\n";
  std::printf("\n%s", evaluate_output(
                          ids, out,
                          [&](int lane) { return out / ("lane" + std::to_string(lane)) / "truth"; },
                          plant.lanes.front().xray.bits, false, acc)
                          .c_str());
  return 0;
}

// A replayed lane's thickness per line (f32 and a PNG in 0.01 mm, 65535 where nothing was
// measured) and its stripe rows; the share of thickness pixels measured. A recording of a
// real line keeps no per-line arrays: nothing written, 0.
double write_lane_thickness(const fs::path& ld, const LaneReplay& r) {
  if (r.thickness.empty()) return 0;
  write_f32(ld / "thickness.f32", r.thickness);
  write_f32(ld / "stripe_cam0.f32", r.stripe_rows[0]);
  write_f32(ld / "stripe_cam1.f32", r.stripe_rows[1]);
  size_t valid = 0;
  std::vector<uint16_t> png(r.thickness.size());
  for (size_t i = 0; i < png.size(); ++i) {
    const float t = r.thickness[i];
    valid += std::isfinite(t);
    png[i] = std::isfinite(t) ? uint16_t(std::clamp(std::lround(t * 100.0), 0L, 65534L)) : 65535;
  }
  write_png16((ld / "thickness.png").string(), png.data(), r.pixels, int(r.lines));
  return double(valid) / double(r.thickness.size());
}

// What `process` wrote of one lane, for its summary.
struct ProcessedLane {
  RecordSet ours;
  double valid = 0;  // share of thickness pixels measured
};

// Everything `process` writes of a replayed lane under out/laneN: thickness, X-ray, each
// fillet's images and the lane's records.
ProcessedLane write_processed_lane(const fs::path& out, const LaneReplay& r,
                                   const RecordingReader& rec, Images images) {
  const fs::path ld = out / ("lane" + std::to_string(r.lane));
  fs::create_directories(ld);
  ProcessedLane p;
  p.valid = write_lane_thickness(ld, r);
  std::vector<uint16_t> xray(size_t(r.lines) * r.pixels);
  rec.read(r.lane, 0, r.lines, nullptr, nullptr, xray.data(), nullptr);
  write_png16((ld / "xray.png").string(), xray.data(), r.pixels, int(r.lines));
  RecordSet base;
  for (const InspectedFillet& f : r.fillets) {
    p.ours.add(f.result);
    base.add(f.baseline);
    maybe_write_images(ld, f, images);
  }
  write_lane_records(ld, p.ours, base);
  return p;
}

double lines_per_second(const LaneReplay& r) {
  return r.seconds > 0 ? double(r.lines) / r.seconds : 0;
}

// The lane's entry in summary.json; with learned thresholds, what its drift monitor would
// have said of this product (`drift`, its sentence).
std::string processed_lane_json(const LaneReplay& r, const ProcessedLane& p,
                                const PlantConfig& plant, std::string& drift) {
  std::ostringstream js;
  js << "{\"lane\": " << r.lane << ", \"lines\": " << r.lines << ", \"pixels\": " << r.pixels
     << ", \"valid_thickness_fraction\": " << p.valid
     << ", \"fusion\": {\"both\": " << r.fusion.both << ", \"single\": " << r.fusion.single
     << ", \"conflict\": " << r.fusion.conflict << ", \"filled\": " << r.fusion.filled
     << ", \"missing\": " << r.fusion.missing << "}, \"fillets\": " << p.ours.fillets.size()
     << ", \"pass\": " << count_decision(p.ours, "pass")
     << ", \"reject\": " << count_decision(p.ours, "reject")
     << ", \"not_inspected\": " << count_decision(p.ours, "not_inspected")
     << ", \"debris\": " << r.assembly.debris << ", \"pipeline_seconds\": " << r.seconds
     << ", \"lines_per_second\": " << lines_per_second(r)
     << ", \"inspection_seconds\": " << r.inspection_seconds;
  if (const LearnedDetection& L = plant.lane(r.lane).inspection.learned; L.active()) {
    const RecordedDrift d = recorded_drift(L, {p.ours}, r.lane);
    js << ", \"drift\": " << drift_json(d);
    drift = drift_sentence(r.lane, d);
  }
  js << "}";
  return js.str();
}

}  // namespace

int cmd_process(int argc, char** argv) {
  const Args a(argc, argv, 2, {"simulate"},
               {"out", "method", "batch", "config", "threads", "images", "lanes", "fillets", "seed",
                "backend", "device", "calibration", "physics"});
  PlantConfig plant = load_config(a.get("config", ""));
  // Replay with new calibrations: --calibration FILE (every lane) or L:FILE,L:FILE.
  if (a.has("calibration")) {
    apply_calibration_option(plant, a.get("calibration", ""));
    plant.calibration_id = a.get("calibration", "");
    if (a.flag("simulate"))
      std::printf("simulating with %s\n", plant.calibration_id.c_str());
    else
      std::printf(
          "replaying %s (made with calibration '%s') with %s\n",
          a.positional(0, "recording folder").c_str(),
          RecordingReader(a.positional(0, "recording folder")).info().calibration_id.c_str(),
          plant.calibration_id.c_str());
  }
  if (a.flag("simulate")) {
    a.expect_positionals(
        0, "process --simulate --out OUT [--lanes N] [--fillets M] [--seed S] [--physics F]");
    if (a.has("method"))
      for (auto& l : plant.lanes) l.stripe.method = parse_stripe_method(a.get("method", ""));
    return process_simulated(a, plant);
  }
  a.expect_positionals(1, "process DIR --out OUT");
  const RecordingReader rec(a.positional(0, "recording folder"));
  for (int lane : rec.info().lanes)
    if (const std::string w = unfitted_constants(plant.lane(lane)); !w.empty())
      std::fprintf(stderr, "warning: %s\n", w.c_str());
  ReplayOptions opt;
  if (a.has("method")) opt.method = parse_stripe_method(a.get("method", ""));
  opt.batch_lines = int(a.integer("batch", 64));
  opt.recalibrated = a.has("calibration");
  // A recording of a real line (a shift rangexd recorded) has no truth and may miss lines:
  // replayed as the server took them.
  opt.missing_lines_ok = !rec.info().has_truth;
  opt.backend = backend_request(a, plant.backend);
  const Images images = parse_images(a.get("images", "all"));
  const fs::path out = a.require("out");
  fs::create_directories(out);
  ProgressBar bar("process");
  BackendInfo backend;
  const auto lanes = replay_recording(
      rec, plant, opt, [&](int64_t d, int64_t t) { bar.update(d, t); }, &backend);
  std::printf("line stages on %s: %s (%s)\n", backend.name.c_str(), backend.device.c_str(),
              backend.driver.c_str());
  std::ostringstream js;
  js << "{\"recording\": " << json_text(rec.dir())
     << ", \"calibration_id\": " << json_text(plant.calibration_id) << ", \"lanes\": [";
  for (size_t li = 0; li < lanes.size(); ++li) {
    const LaneReplay& r = lanes[li];
    const ProcessedLane p = write_processed_lane(out, r, rec, images);
    std::string drift;
    js << (li ? ", " : "") << processed_lane_json(r, p, plant, drift);
    char thickness[64] = "a recording of a real line";  // per-line arrays not kept
    if (!r.thickness.empty())
      std::snprintf(thickness, sizeof thickness, "%.1f%% of thickness pixels valid",
                    100.0 * p.valid);
    std::printf(
        "lane %d: %lld lines, %s, %zu fillets (%d pass, %d reject, %d not inspected), %.0f "
        "lines/s (%s)\n",
        r.lane, (long long)r.lines, thickness, p.ours.fillets.size(),
        count_decision(p.ours, "pass"), count_decision(p.ours, "reject"),
        count_decision(p.ours, "not_inspected"), lines_per_second(r), backend.name.c_str());
    if (!drift.empty()) std::printf("%s\n", drift.c_str());
  }
  js << "]}\n";
  std::ofstream(out / "summary.json") << js.str();
  std::printf(
      "wrote %s (per lane: fillets.csv/json, fragments.csv, thickness.png in 0.01 mm, "
      "fillet_*/ images; summary.json)\n",
      out.c_str());
  return 0;
}

int cmd_eval(int argc, char** argv) {
  const Args a(argc, argv, 2, {"json"}, {"config"});
  const PlantConfig plant = load_config(a.get("config", ""));
  const int bits = plant.lanes.front().xray.bits;
  if (a.positional().size() == 1) {
    // A simulated run: truth and line accuracy live in the output folder.
    const fs::path out = a.positional(0, "output folder");
    std::vector<int> ids;
    std::vector<LaneEvaluation> acc;
    for (const auto& e : fs::directory_iterator(out)) {
      const std::string name = e.path().filename().string();
      if (!e.is_directory() || name.rfind("lane", 0) != 0) continue;
      const int lane = std::stoi(name.substr(4));
      ids.push_back(lane);
      acc.push_back(read_line_accuracy((e.path() / "line_accuracy.csv").string(), lane));
    }
    if (ids.empty()) fail(out.string(), " holds no lane results");
    std::vector<size_t> order(ids.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return ids[x] < ids[y]; });
    std::vector<int> sid;
    std::vector<LaneEvaluation> sacc;
    for (size_t i : order) sid.push_back(ids[i]), sacc.push_back(acc[i]);
    std::fputs(
        evaluate_output(
            sid, out, [&](int lane) { return out / ("lane" + std::to_string(lane)) / "truth"; },
            bits, a.flag("json"), sacc)
            .c_str(),
        stdout);
    return 0;
  }
  a.expect_positionals(2, "eval DIR OUT [--json]  or  eval OUT (a simulated run)");
  const RecordingReader rec(a.positional(0, "recording folder"));
  const fs::path out = a.positional(1, "output folder");
  const RecordingInfo& info = rec.info();
  std::vector<LaneEvaluation> evs;
  std::vector<int> ids;
  for (int lane : info.lanes) {
    const fs::path ld = out / ("lane" + std::to_string(lane));
    if (!fs::exists(ld)) continue;
    std::vector<float> rows[2] = {
        read_f32(ld / "stripe_cam0.f32", size_t(info.lines) * info.width),
        read_f32(ld / "stripe_cam1.f32", size_t(info.lines) * info.width)};
    const auto t = read_f32(ld / "thickness.f32", size_t(info.lines) * info.xray_pixels);
    evs.push_back(evaluate_lane(rec, plant.lane(lane), rows, t));
    ids.push_back(lane);
  }
  if (evs.empty()) fail(out.string(), " holds no processed lane of ", rec.dir());
  std::fputs(evaluate_output(
                 ids, out, [&](int lane) { return fs::path(rec.lane_dir(lane)) / "truth"; }, bits,
                 a.flag("json"), evs)
                 .c_str(),
             stdout);
  return 0;
}

}  // namespace rangex::cli
