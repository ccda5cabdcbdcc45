#include "offline/plant_run.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "core/error.h"
#include "offline/line_path.h"
#include "pipeline/truth_heights.h"

namespace rangex {

namespace {
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

std::vector<PlantRunLane> run_simulated_plant(const PlantConfig& plant,
                                              const sim::SimulationParams& sp,
                                              const PlantRunOptions& opt,
                                              const std::function<void(int64_t, int64_t)>& progress,
                                              BackendInfo* backend_info) {
  if (sp.lanes <= 0 || sp.lanes > int(plant.lanes.size()))
    fail("cannot simulate ", sp.lanes, " lanes: the plant configuration has ", plant.lanes.size());
  std::vector<sim::LaneSimulator> sims;
  int64_t total = 0;
  for (int i = 0; i < sp.lanes; ++i) {
    sims.emplace_back(plant.lanes[i], sp);
    total += sims.back().lines();
  }
  int64_t done = 0;
  std::vector<PlantRunLane> out;
  const int threads = std::max(1, opt.threads);
  // One line path for every simulated lane, as the server runs its lanes.
  LinePath path({plant.lanes.begin(), plant.lanes.begin() + sp.lanes}, opt.backend);
  if (backend_info) *backend_info = path.backend();
  std::vector<QueuedLine> block;
  for (int li = 0; li < sp.lanes; ++li) {
    const LaneConfig& lc = plant.lanes[li];
    const sim::LaneSimulator& sim = sims[li];
    PlantRunLane lane;
    lane.lane = lc.id;
    lane.lines = sim.lines();
    lane.truth_fragments_csv = sim.fragments_csv();
    lane.truth_fillets_csv = sim.fillets_csv();
    const int W = lc.frame_width, H = lc.frame_height, D = lc.xray.pixels,
              delay = lc.xray.delay_lines;
    const size_t frame = size_t(W) * H;
    constexpr int kBlock = 64;
    std::vector<uint16_t> xray(size_t(D) * kBlock),
        high(lc.xray.energies == 2 ? xray.size() : 0);  // a lane of two energies' high lines
    const bool dual = !high.empty();
    std::vector<float> rows(size_t(2 * W) * kBlock), truth_t(size_t(D) * kBlock);
    const TruthHeights truth_heights[2] = {TruthHeights(lc, 0), TruthHeights(lc, 1)};
    ErrorAccumulator stripe_all[2], stripe_fillet[2], thick;
    size_t truth_cols[2] = {0, 0}, found_cols[2] = {0, 0}, blank_cols[2] = {0, 0},
           false_cols[2] = {0, 0};
    size_t fillet_px = 0, measured_px = 0;
    std::map<int64_t, std::vector<float>> registered;  // X-ray line -> measured thickness
    int64_t n0 = 0;
    const LinePath::Observer observe = [&](const std::vector<QueuedLine>& lines,
                                           const LineResults& res) {
      std::vector<float> tz(W);
      std::vector<uint8_t> tv2(W);
      for (int k = 0; k < int(lines.size()); ++k) {
        const int64_t n = lines[k].line.encoder - sim.encoder(0);
        for (int c = 0; c < 2; ++c) {
          const float* truth = &rows[size_t(2 * k + c) * W];
          const float* meas = &res.stripes.row[size_t(2 * k + c) * W];
          truth_heights[c].heights(truth, 1, W, tz.data(), tv2.data());
          for (int u = 0; u < W; ++u) {
            const bool t = std::isfinite(truth[u]), m = std::isfinite(meas[u]);
            truth_cols[c] += t;
            found_cols[c] += t && m;
            blank_cols[c] += !t;
            false_cols[c] += !t && m;
            if (t && m) {
              stripe_all[c].add(double(meas[u]) - truth[u]);
              if (tz[u] > kFilletColumnMinMm) stripe_fillet[c].add(double(meas[u]) - truth[u]);
            }
          }
        }
        auto& reg = registered[n + delay];
        reg.resize(D);
        for (int i = 0; i < D; ++i) {
          const size_t o = size_t(k) * D + i;
          reg[i] = res.thickness_valid[o] ? res.thickness[o] : NAN;
        }
      }
    };
    LaneProcessor proc(lc, {true, opt.keep_images || bool(opt.on_fillet)},
                       [&](InspectedFillet&& f) {
                         if (opt.on_fillet) opt.on_fillet(f);
                         lane.ours.add(f.result);
                         lane.baseline.add(f.baseline);
                       });
    path.attach(lc.id, &proc);
    const double stages_before = path.stage_seconds();
    for (n0 = 0; n0 < sim.lines(); n0 += kBlock) {
      const int count = int(std::min<int64_t>(kBlock, sim.lines() - n0));
      // Frames are rendered into the lines as the server receives them.
      shape_block(block, count, lc.id, frame, D);
      const auto t0 = std::chrono::steady_clock::now();
      std::vector<std::thread> pool;
      for (int w = 0; w < threads; ++w)
        pool.emplace_back([&, w] {
          for (int k = w; k < count; k += threads)
            sim.render(n0 + k, reinterpret_cast<uint8_t*>(block[k].line.cam0.data()),
                       reinterpret_cast<uint8_t*>(block[k].line.cam1.data()), &xray[size_t(D) * k],
                       &rows[size_t(2 * k) * W], &rows[size_t(2 * k + 1) * W],
                       &truth_t[size_t(D) * k], dual ? &high[size_t(D) * k] : nullptr);
        });
      for (auto& t : pool) t.join();
      for (int k = 0; k < count; ++k) {
        block[k].line.encoder = sim.encoder(n0 + k);
        std::memcpy(block[k].line.xray.data(), &xray[size_t(D) * k], size_t(D) * sizeof(uint16_t));
        block[k].line.xray_high.resize(dual ? size_t(D) * sizeof(uint16_t) : 0);
        if (dual)
          std::memcpy(block[k].line.xray_high.data(), &high[size_t(D) * k],
                      size_t(D) * sizeof(uint16_t));
      }
      lane.render_s += since(t0);
      path.run(block, observe);
      // Thickness accuracy: X-ray line n's truth against the camera line n - delay.
      for (int k = 0; k < count; ++k) {
        auto it = registered.find(n0 + k);
        if (it == registered.end()) continue;
        for (int i = 0; i < D; ++i) {
          const float t = truth_t[size_t(k) * D + i];
          if (!(t >= kFilletPixelMinMm)) continue;
          ++fillet_px;
          if (std::isfinite(it->second[i])) {
            ++measured_px;
            thick.add(double(it->second[i]) - t);
          }
        }
        registered.erase(it);
      }
      done += count;
      if (progress) progress(done, total);
    }
    proc.finish();
    lane.pipeline_s = path.stage_seconds() - stages_before;
    lane.assembly = proc.assembly();
    lane.fusion = path.fusion(lc.id);
    lane.inspection_s = proc.inspection_seconds();
    LaneEvaluation& ev = lane.accuracy;
    ev.lane = lc.id;
    for (int c = 0; c < 2; ++c) {
      ev.stripe[c] = stripe_all[c].stats();
      ev.stripe_fillet[c] = stripe_fillet[c].stats();
      ev.stripe_detected[c] = truth_cols[c] ? double(found_cols[c]) / truth_cols[c] : 0;
      ev.stripe_false[c] = blank_cols[c] ? double(false_cols[c]) / blank_cols[c] : 0;
    }
    ev.thickness = thick.stats();
    ev.fillet_coverage = fillet_px ? double(measured_px) / fillet_px : 0;
    out.push_back(std::move(lane));
  }
  return out;
}

void write_line_accuracy(const std::string& path, const LaneEvaluation& e) {
  std::ofstream out(path);
  out.precision(9);
  out << "key,value\n";
  auto stats = [&](const std::string& k, const ErrorStats& s) {
    out << k << ".count," << s.count << "\n"
        << k << ".mean_abs," << s.mean_abs << "\n"
        << k << ".p99_abs," << s.p99_abs << "\n"
        << k << ".bias," << s.bias << "\n";
  };
  for (int c = 0; c < 2; ++c) {
    stats("stripe_cam" + std::to_string(c), e.stripe[c]);
    stats("stripe_fillet_cam" + std::to_string(c), e.stripe_fillet[c]);
    out << "stripe_detected_cam" << c << "," << e.stripe_detected[c] << "\n";
    out << "stripe_false_cam" << c << "," << e.stripe_false[c] << "\n";
  }
  stats("thickness", e.thickness);
  out << "fillet_coverage," << e.fillet_coverage << "\n";
  if (!out) fail(path, ": write failed");
}

LaneEvaluation read_line_accuracy(const std::string& path, int lane) {
  std::ifstream in(path);
  if (!in) fail(path, " is missing");
  std::map<std::string, double> kv;
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    const auto comma = line.find(',');
    if (comma == std::string::npos) fail(path, ": malformed line '", line, "'");
    kv[line.substr(0, comma)] = std::stod(line.substr(comma + 1));
  }
  auto get = [&](const std::string& k) {
    auto it = kv.find(k);
    if (it == kv.end()) fail(path, ": missing ", k);
    return it->second;
  };
  auto stats = [&](const std::string& k) {
    ErrorStats s;
    s.count = size_t(get(k + ".count"));
    s.mean_abs = get(k + ".mean_abs");
    s.p99_abs = get(k + ".p99_abs");
    s.bias = get(k + ".bias");
    return s;
  };
  LaneEvaluation e;
  e.lane = lane;
  for (int c = 0; c < 2; ++c) {
    e.stripe[c] = stats("stripe_cam" + std::to_string(c));
    e.stripe_fillet[c] = stats("stripe_fillet_cam" + std::to_string(c));
    e.stripe_detected[c] = get("stripe_detected_cam" + std::to_string(c));
    e.stripe_false[c] = get("stripe_false_cam" + std::to_string(c));
  }
  e.thickness = stats("thickness");
  e.fillet_coverage = get("fillet_coverage");
  return e;
}

}  // namespace rangex
