// simulate, extract, process, eval: the offline commands over recordings.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <thread>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "core/png_io.h"
#include "evaluation.h"
#include "progress_bar.h"
#include "replay.h"
#include "sim/plant_simulator.h"

namespace fs = std::filesystem;

namespace rangex::cli {

std::string config_path(const std::string& opt) {
  if (!opt.empty()) return opt;
  if (const char* env = std::getenv("RANGEX_CONFIG")) return env;
  if (fs::exists("config/plant.yaml")) return "config/plant.yaml";
  return RANGEX_DEFAULT_CONFIG;
}

PlantConfig load_config(const std::string& opt) { return load_plant_config(config_path(opt)); }

namespace {

void write_f32(const fs::path& p, const std::vector<float>& v) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * sizeof(float)));
  if (!out) fail(p.string(), ": write failed");
}

std::vector<float> read_f32(const fs::path& p, size_t expect) {
  if (!fs::exists(p)) fail(p.string(), " is missing (was the output written by 'rangexctl process'?)");
  if (fs::file_size(p) != expect * sizeof(float))
    fail(p.string(), " holds ", fs::file_size(p), " bytes, expected ", expect * sizeof(float));
  std::vector<float> v(expect);
  std::ifstream in(p, std::ios::binary);
  in.read(reinterpret_cast<char*>(v.data()), std::streamsize(expect * sizeof(float)));
  return v;
}

}  // namespace

int cmd_simulate(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, {"lanes", "fillets", "seed", "out", "config"});
  a.expect_positionals(0, "simulate --out DIR [--lanes N] [--fillets M] [--seed S]");
  const PlantConfig plant = load_config(a.get("config", ""));
  sim::SimulationParams p;
  p.lanes = int(a.integer("lanes", long(plant.lanes.size())));
  p.scene.fillets = int(a.integer("fillets", 5));
  p.seed = uint64_t(a.integer("seed", 1));
  const std::string out = a.require("out");
  ProgressBar bar("simulate");
  sim::simulate_recording(plant, p, out, [&](int64_t d, int64_t t) { bar.update(d, t); });
  const RecordingReader rec(out);
  std::printf("wrote %s: %zu lanes x %lld lines, %d fillets per lane, seed %llu\n", out.c_str(),
              rec.info().lanes.size(), (long long)rec.info().lines, p.scene.fillets,
              (unsigned long long)p.seed);
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
  const int W = rec.info().width, H = rec.info().height;
  const size_t frame = size_t(W) * H;
  constexpr int kBatch = 64;
  std::vector<uint8_t> frames(frame * kBatch);
  std::vector<int> slots(kBatch, 0);
  StripeOutput so;
  ProgressBar bar("extract");
  char buf[64];
  for (int64_t n0 = 0; n0 < rec.info().lines; n0 += kBatch) {
    const int count = int(std::min<int64_t>(kBatch, rec.info().lines - n0));
    rec.read(lane, n0, count, camera == 0 ? frames.data() : nullptr,
             camera == 1 ? frames.data() : nullptr, nullptr, nullptr);
    extract_stripes(frames.data(), count, W, H, slots.data(), &slot, so);
    for (int k = 0; k < count; ++k)
      for (int c = 0; c < W; ++c) {
        const size_t o = size_t(k) * W + c;
        if (so.valid[o]) std::snprintf(buf, sizeof buf, "%lld,%d,%.4f\n", (long long)(n0 + k), c, so.row[o]);
        else std::snprintf(buf, sizeof buf, "%lld,%d,\n", (long long)(n0 + k), c);
        out << buf;
      }
    bar.update(n0 + count, rec.info().lines);
  }
  if (!out) fail(out_path, ": write failed");
  return 0;
}

int cmd_process(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, {"out", "method", "batch", "config", "threads"});
  a.expect_positionals(1, "process DIR --out OUT");
  const RecordingReader rec(a.positional(0, "recording folder"));
  const PlantConfig plant = load_config(a.get("config", ""));
  ReplayOptions opt;
  if (a.has("method")) opt.method = parse_stripe_method(a.get("method", ""));
  opt.batch_lines = int(a.integer("batch", 64));
  opt.threads = int(a.integer("threads", long(std::max(1u, std::thread::hardware_concurrency()))));
  if (opt.threads < 1) fail("--threads must be >= 1 (got ", opt.threads, ")");
  const fs::path out = a.require("out");
  fs::create_directories(out);
  ProgressBar bar("process");
  const auto lanes = replay_recording(rec, plant, opt, [&](int64_t d, int64_t t) { bar.update(d, t); });
  std::ostringstream js;
  js << "{\"recording\": \"" << rec.dir() << "\", \"calibration_id\": \"" << plant.calibration_id
     << "\", \"lanes\": [";
  for (size_t li = 0; li < lanes.size(); ++li) {
    const LaneReplay& r = lanes[li];
    const fs::path ld = out / ("lane" + std::to_string(r.lane));
    fs::create_directories(ld);
    write_f32(ld / "thickness.f32", r.thickness);
    write_f32(ld / "stripe_cam0.f32", r.stripe_rows[0]);
    write_f32(ld / "stripe_cam1.f32", r.stripe_rows[1]);
    // Thickness PNG: 0.01 mm per count, 65535 where nothing was measured.
    std::vector<uint16_t> png(r.thickness.size());
    size_t valid = 0;
    for (size_t i = 0; i < png.size(); ++i) {
      const float t = r.thickness[i];
      valid += std::isfinite(t);
      png[i] = std::isfinite(t) ? uint16_t(std::clamp(std::lround(t * 100.0), 0L, 65534L)) : 65535;
    }
    write_png16((ld / "thickness.png").string(), png.data(), r.pixels, int(r.lines));
    std::vector<uint16_t> xray(size_t(r.lines) * r.pixels);
    rec.read(r.lane, 0, r.lines, nullptr, nullptr, xray.data(), nullptr);
    write_png16((ld / "xray.png").string(), xray.data(), r.pixels, int(r.lines));
    const double lines_per_s = r.seconds > 0 ? double(r.lines) / r.seconds : 0;
    js << (li ? ", " : "") << "{\"lane\": " << r.lane << ", \"lines\": " << r.lines
       << ", \"pixels\": " << r.pixels << ", \"valid_thickness_fraction\": "
       << double(valid) / double(std::max<size_t>(1, png.size()))
       << ", \"fusion\": {\"both\": " << r.fusion.both << ", \"single\": " << r.fusion.single
       << ", \"conflict\": " << r.fusion.conflict << ", \"filled\": " << r.fusion.filled
       << ", \"missing\": " << r.fusion.missing << "}, \"pipeline_seconds\": " << r.seconds
       << ", \"lines_per_second\": " << lines_per_s << "}";
    std::printf("lane %d: %lld lines, %.1f%% of thickness pixels valid, %.0f lines/s (CPU, %d threads)\n",
                r.lane, (long long)r.lines, 100.0 * double(valid) / double(std::max<size_t>(1, png.size())),
                lines_per_s, opt.threads);
  }
  js << "]}\n";
  std::ofstream(out / "summary.json") << js.str();
  std::printf("wrote %s (thickness.png in 0.01 mm, 65535 = not measured; summary.json)\n",
              out.c_str());
  return 0;
}

int cmd_eval(int argc, char** argv) {
  const Args a(argc, argv, 2, {"json"}, {"config"});
  a.expect_positionals(2, "eval DIR OUT [--json]");
  const RecordingReader rec(a.positional(0, "recording folder"));
  const fs::path out = a.positional(1, "output folder");
  const RecordingInfo& info = rec.info();
  const PlantConfig plant = load_config(a.get("config", ""));
  std::vector<LaneEvaluation> evs;
  for (int lane : info.lanes) {
    const fs::path ld = out / ("lane" + std::to_string(lane));
    if (!fs::exists(ld)) continue;
    std::vector<float> rows[2] = {read_f32(ld / "stripe_cam0.f32", size_t(info.lines) * info.width),
                                  read_f32(ld / "stripe_cam1.f32", size_t(info.lines) * info.width)};
    const auto t = read_f32(ld / "thickness.f32", size_t(info.lines) * info.xray_pixels);
    evs.push_back(evaluate_lane(rec, plant.lane(lane), rows, t));
  }
  if (evs.empty()) fail(out.string(), " holds no processed lane of ", rec.dir());
  std::fputs(a.flag("json") ? (evaluations_json(evs) + "\n").c_str() : evaluations_table(evs).c_str(), stdout);
  return 0;
}

}  // namespace rangex::cli
