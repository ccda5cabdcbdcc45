#include "bench/bench_path.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "core/error.h"
#include "core/heap_trim.h"
#include "pipeline/lane_learning.h"
#include "pipeline/lane_processor.h"
#include "pipeline/line_pipeline.h"
#include "pipeline/product_learning.h"
#include "sim/plant_simulator.h"

namespace rangex::cli {

namespace {

using clk = std::chrono::steady_clock;

// The rows of the report: the line stages, the assembly, the inspection's own stages.
enum Row { kIngest, kStripe, kRectify, kFuse, kProject, kAssemble, kInspect0 };
constexpr int kInspectStages = kStages;
constexpr int kRows = kInspect0 + kInspectStages + 1;  // + the inspection's remainder
const char* row_name(int r) {
  static const char* kLine[] = {"ingest copy", "stripe", "rectify", "fuse", "project", "assemble"};
  if (r < kInspect0) return kLine[r];
  if (r < kInspect0 + kInspectStages) return inspect_stage_name(r - kInspect0);
  return "inspection, other";
}

// One lane's simulated lines, rendered once and fed to every lane of a run.
struct Recorded {
  int width = 0, height = 0, pixels = 0, lines = 0;
  std::vector<uint8_t> frames;  // [line][camera][row][column]
  std::vector<uint16_t> xray;   // [line][pixel]
  std::vector<int64_t> encoders;
  size_t frame() const { return size_t(width) * height; }
};

Recorded render(const LaneConfig& lc, int lines) {
  sim::SimulationParams sp;
  sp.scene.fillets = std::max(2, lines / 400);
  sp.scene.lead_in_mm = 5;
  const sim::LaneSimulator sim(lc, sp);
  Recorded r;
  r.width = lc.frame_width, r.height = lc.frame_height, r.pixels = lc.xray.pixels;
  r.lines = int(std::min<int64_t>(lines, sim.lines()));
  r.frames.resize(r.frame() * 2 * r.lines);
  r.xray.resize(size_t(r.pixels) * r.lines);
  r.encoders.resize(r.lines);
  const int threads = int(std::max(1u, std::thread::hardware_concurrency()));
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      for (int n = t; n < r.lines; n += threads)
        sim.render(n, &r.frames[r.frame() * 2 * n], &r.frames[r.frame() * (2 * n + 1)],
                   &r.xray[size_t(r.pixels) * n], nullptr, nullptr, nullptr);
    });
  for (auto& t : pool) t.join();
  for (int n = 0; n < r.lines; ++n) r.encoders[n] = sim.encoder(n);
  return r;
}

// One core's sequential read bandwidth over the frames (the bound of the line path).
double read_bandwidth(const Recorded& r) {
  volatile uint64_t sink = 0;
  std::vector<double> gbs;
  for (int pass = 0; pass < 5; ++pass) {
    const auto t0 = clk::now();
    const uint64_t* p = reinterpret_cast<const uint64_t*>(r.frames.data());
    const size_t n = r.frames.size() / 8;
    uint64_t s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    for (size_t i = 0; i + 3 < n; i += 4)
      s0 += p[i], s1 += p[i + 1], s2 += p[i + 2], s3 += p[i + 3];
    sink = sink + s0 + s1 + s2 + s3;
    gbs.push_back(double(r.frames.size()) / std::chrono::duration<double>(clk::now() - t0).count() /
                  1e9);
  }
  std::sort(gbs.begin(), gbs.end());
  return gbs[gbs.size() / 2];
}

struct PathTimes {
  double seconds[kRows] = {};
  double wall = 0;
  int64_t lines = 0;
  int fillets = 0;
  int64_t fillet_pixels = 0;
  double bytes_copied = 0;
  void add(const PathTimes& o) {
    for (int r = 0; r < kRows; ++r) seconds[r] += o.seconds[r];
    lines += o.lines, fillets += o.fillets, fillet_pixels += o.fillet_pixels;
    bytes_copied += o.bytes_copied;
  }
  double total() const {
    double s = 0;
    for (double v : seconds) s += v;
    return s;
  }
};

// Lanes first_lane .. first_lane + lanes - 1 through the whole path on the calling thread,
// in batches that mix the lanes line by line, as the server's batches do.
// With `images`, the fillets cut are handed to it uninspected.
PathTimes run_lanes(const LaneConfig& lc, const Recorded& rec, int first_lane, int lanes, int batch,
                    LaneProcessor::ImageSink images = {}) {
  std::vector<LaneConfig> cfgs;
  for (int q = 0; q < lanes; ++q) {
    LaneConfig c = lc;
    c.id = first_lane + q;
    cfgs.push_back(c);
  }
  const LinePipeline pipe(cfgs, 1);
  PathTimes t;
  double inspected = 0;  // inspection seconds reported by the sink
  std::vector<std::unique_ptr<LaneProcessor>> procs;
  for (int q = 0; q < lanes; ++q)
    procs.push_back(std::make_unique<LaneProcessor>(
        cfgs[q], LaneProcessorOptions{false, false},
        [&](InspectedFillet&& f) {
          double staged = 0;
          for (int s = 0; s < kStages; ++s) {
            t.seconds[kInspect0 + s] += f.result.stage_seconds[s];
            staged += f.result.stage_seconds[s];
          }
          t.seconds[kInspect0 + kInspectStages] += std::max(0.0, f.inspect_ms / 1e3 - staged);
          inspected += f.inspect_ms / 1e3;
          ++t.fillets;
          t.fillet_pixels += f.result.pixels;
        },
        images));
  const int per = std::max(1, batch / lanes);  // line indices per batch
  const size_t frame = rec.frame();
  const int W = rec.width, G = pipe.grid_samples(), P = rec.pixels;
  std::vector<uint8_t> staging(size_t(per) * lanes * 2 * frame);
  std::vector<int> lane_slot(size_t(per) * lanes), frame_slot(2 * lane_slot.size());
  StripeOutput so;
  std::vector<float> x, z, prof, thick;
  std::vector<uint8_t> xzv, pv, tv;
  FusionStats fs;
  const auto start = clk::now();
  auto t0 = start;
  auto lap = [&](int row) {
    const auto now = clk::now();
    t.seconds[row] += std::chrono::duration<double>(now - t0).count();
    t0 = now;
  };
  // The assembly's time is that of push() less the inspection it triggered.
  auto assembled = [&](double before) {
    const auto now = clk::now();
    const double spent = std::chrono::duration<double>(now - t0).count();
    t.seconds[kAssemble] += std::max(0.0, spent - (inspected - before));
    t0 = now;
  };
  for (int n0 = 0; n0 < rec.lines; n0 += per) {
    const int cnt = std::min(per, rec.lines - n0), L = cnt * lanes;
    t0 = clk::now();
    for (int k = 0; k < cnt; ++k)
      for (int q = 0; q < lanes; ++q) {
        const int j = k * lanes + q;
        std::memcpy(&staging[size_t(j) * 2 * frame], &rec.frames[size_t(n0 + k) * 2 * frame],
                    2 * frame);
        lane_slot[j] = q;
        frame_slot[2 * j] = 2 * q, frame_slot[2 * j + 1] = 2 * q + 1;
      }
    t.bytes_copied += double(L) * 2 * frame;
    lap(kIngest);
    pipe.stripes(staging.data(), 2 * L, frame_slot.data(), so);
    lap(kStripe);
    x.resize(size_t(2 * L) * W), z.resize(x.size()), xzv.resize(x.size());
    pipe.rectify_rows(so.row.data(), so.valid.data(), 2 * L, frame_slot.data(), x.data(), z.data(),
                      xzv.data());
    lap(kRectify);
    prof.resize(size_t(L) * G), pv.resize(prof.size());
    pipe.fuse(x.data(), z.data(), xzv.data(), L, lane_slot.data(), prof.data(), pv.data(), &fs);
    lap(kFuse);
    thick.resize(size_t(L) * P), tv.resize(thick.size());
    pipe.project(prof.data(), pv.data(), L, lane_slot.data(), thick.data(), tv.data());
    lap(kProject);
    const double before = inspected;
    for (int k = 0; k < cnt; ++k)
      for (int q = 0; q < lanes; ++q) {
        const size_t j = size_t(k) * lanes + q;
        procs[q]->push(&thick[j * P], &tv[j * P], &rec.xray[size_t(n0 + k) * P],
                       rec.encoders[n0 + k], LaneProcessor::blind(&pv[j * G], G));
      }
    assembled(before);
  }
  t0 = clk::now();
  const double before = inspected;
  for (auto& p : procs) p->finish();
  assembled(before);
  t.wall = std::chrono::duration<double>(clk::now() - start).count();
  t.lines = int64_t(rec.lines) * lanes;
  return t;
}

// Bytes a stage must touch per line (read + written), its memory bound at the read bandwidth.
double bytes_per_line(int row, const Recorded& r, int grid, const PathTimes& t) {
  const double W = r.width, F = double(r.frame()), G = grid, P = r.pixels;
  const double px = t.lines ? double(t.fillet_pixels) / double(t.lines) : 0;
  switch (row) {
    case kIngest:
      return 2 * 2 * F;  // both frames read and written once
    case kStripe:
      return 2 * F + 2 * W * 5;  // frames in; row (float) and valid flag per column out
    case kRectify:
      return 2 * W * 5 + 2 * W * 9;  // rows in; x, z, valid out
    case kFuse:
      return 2 * W * 9 + G * 5;
    case kProject:
      return G * 5 + P * 5;
    case kAssemble:
      return P * 7 + P * 7;  // thickness, flag, X-ray in; the fillet image's pixels out
    default:
      return px * 11;  // one pass over the fillet image: thickness, X-ray, mask in; a float out
  }
}

void report(const char* title, const PathTimes& t, const Recorded& rec, int grid, double gbs) {
  const double total = t.total(), per_line_us = 1e6 * total / double(t.lines);
  std::printf("\n%s: %lld lines, %d fillets; %.0f lines/s on one core (%.3f of the read bound)\n",
              title, (long long)t.lines, t.fillets, double(t.lines) / total,
              (double(t.lines) / total) / (gbs * 1e9 / (2.0 * double(rec.frame()))));
  std::printf("  %-20s %10s %8s %12s %10s %14s\n", "stage", "us/line", "share", "bytes/line",
              "bound us", "of its bound");
  for (int r = 0; r < kRows; ++r) {
    const double us = 1e6 * t.seconds[r] / double(t.lines);
    const double bytes = bytes_per_line(r, rec, grid, t);
    const double bound_us = 1e6 * bytes / (gbs * 1e9);
    std::printf("  %-20s %10.2f %7.1f%% %12.0f %10.2f %14.3f\n", row_name(r), us,
                100 * t.seconds[r] / total, bytes, bound_us, us > 0 ? bound_us / us : 0.0);
  }
  std::printf("  %-20s %10.2f %7.1f%%\n", "total", per_line_us, 100.0);
  if (t.fillets) {
    double insp = 0;
    for (int r = kInspect0; r < kRows; ++r) insp += t.seconds[r];
    std::printf("  inspection: %.2f ms per fillet (%.0f fillet pixels each);",
                1e3 * insp / t.fillets, double(t.fillet_pixels) / t.fillets);
    for (int r = kInspect0; r < kRows; ++r)
      std::printf(" %s %.2f", row_name(r), 1e3 * t.seconds[r] / t.fillets);
    std::printf(" ms\n");
  }
  std::printf("  bytes copied per line: %.0f (%.2f frames' worth)\n",
              t.bytes_copied / double(t.lines),
              t.bytes_copied / double(t.lines) / (2.0 * double(rec.frame())));
}

// Today's inspection of the same fillets on a thread of its own, as rangexd's lanes inspect,
// under heap policies (heap_trim.h) in alternating rounds: the server's before 2026-12-02
// (blocks of 256 kB and more mapped, an arena's free top returned beyond glibc's 128 kB:
// each fillet's buffers went back to the kernel and came back as page faults), that with the
// top kept, and today's. The process keeps today's afterwards.
void bench_server_heap(const std::vector<FilletImage>& imgs, const InspectionParams& p) {
  constexpr int kPolicies = 3;
  const size_t mapped[kPolicies] = {size_t(256) << 10, size_t(256) << 10, kMappedBlockBytes};
  const size_t kept[kPolicies] = {size_t(128) << 10, kArenaKeptTopBytes, kArenaKeptTopBytes};
  std::vector<double> ms[kPolicies];
  constexpr int kRounds = 5;
  for (int round = 0; round < kRounds; ++round)
    for (int k = 0; k < kPolicies; ++k) {
      set_server_heap_policy(mapped[k], kept[k]);
      double t = 0;
      std::thread([&] {
        const auto t0 = clk::now();
        for (const FilletImage& im : imgs) inspect_fillet(im, p, false);
        t = std::chrono::duration<double>(clk::now() - t0).count();
      }).join();
      ms[k].push_back(1e3 * t / double(imgs.size()));
    }
  std::printf(
      "\ntoday's inspection on a thread of its own under the server's heap policy, ms per "
      "fillet (median of %d alternating rounds):\n",
      kRounds);
  double base = 0;
  for (int k = 0; k < kPolicies; ++k) {
    std::sort(ms[k].begin(), ms[k].end());
    const double m = ms[k][ms[k].size() / 2];
    if (k == 0) base = m;
    std::printf("  blocks from %5.2f MB mapped, arena keeps %5.2f MB %8.2f  (%.2fx)\n",
                double(mapped[k]) / (1 << 20), double(kept[k]) / (1 << 20), m,
                base > 0 ? m / base : 0.0);
  }
}

// Compensation and detection of the same fillets before product learning (one spread per fillet,
// fixed thresholds, no band extremes) and after it (band extremes; fixed and learned
// thresholds; one spread per fillet and spread by thickness; whitened round kernels, and
// whitened needle kernels beside them; those after the bright enclosure, and with air pockets
// flattened too, with needles of one width and a bank of two; and without the outline carried
// as a wall), in alternating rounds; medians of the rounds, as ratios to the first.
void bench_inspection(const LaneConfig& lc, const Recorded& rec, int batch) {
  std::vector<FilletImage> imgs;
  run_lanes(lc, rec, 0, 1, batch, [&](FilletImage&& im) { imgs.push_back(std::move(im)); });
  if (imgs.empty()) return;
  constexpr int kVariants = 10;
  InspectionParams v[kVariants];
  const char* names[kVariants] = {"before learning (fixed, no extremes)",
                                  "fixed, band extremes",
                                  "learned, round Gaussian",
                                  "learned, spread by thickness",
                                  "learned, whitened round kernels",
                                  "learned, whitened round and needle kernels",
                                  "learned, whitened kernels, bright enclosure",
                                  "learned, enclosure and voids, 0.6 mm needles",
                                  "the same, needles of 0.6 and 1.0 mm",
                                  "enclosure and voids, outline not a wall"};
  for (int k = 0; k < kVariants; ++k) {
    v[k] = lc.inspection;
    v[k].learned = LearnedDetection{};
    v[k].band_extremes = k > 0;
    v[k].spread_by_thickness = k == 3;
  }
  // The kernels with the clip alone, then with the bright enclosure before it, then with air
  // pockets flattened as well.
  InspectionParams kernels = lc.inspection;
  kernels.matched_enclosure = false;
  kernels.matched_void_factor = 0;
  kernels.matched_needle_diameters_mm = {0.6};  // one width, whatever the lane sets
  v[5].learned.matched = learn_lane_kernels(imgs, kernels);
  v[4].learned.matched = v[5].learned.matched;
  v[4].learned.matched.drop_needles();
  kernels.matched_enclosure = true;
  v[6].learned.matched = learn_lane_kernels(imgs, kernels);
  kernels.matched_void_factor = lc.inspection.matched_void_factor > 0
                                    ? lc.inspection.matched_void_factor
                                    : InspectionParams{}.matched_void_factor;
  v[7].learned.matched = learn_lane_kernels(imgs, kernels);
  kernels.matched_needle_diameters_mm = {0.6, 1.0};
  v[8].learned.matched = learn_lane_kernels(imgs, kernels);
  // Today's kernels (v[7]) with the fillet's outline not carried as a wall (rim_walls).
  v[9].learned.matched = v[7].learned.matched;
  v[9].rim_walls = false;
  // Thresholds learned on these few fillets: for the timing, not for a decision.
  for (int k : {2, 3, 4, 5, 6, 7, 8, 9}) {
    std::vector<LearningFillet> fs;
    for (const FilletImage& im : imgs)
      fs.push_back({0, im.id, 0, inspect_fillet(im, v[k], false).extremes});
    LearnOptions lo;
    lo.min_fillets = 1;
    lo.bootstrap = 20;
    lo.spread_by_thickness = v[k].spread_by_thickness;
    lo.rim_walls = v[k].rim_walls;
    try {
      const MatchedKernels kernels = v[k].learned.matched;
      v[k].learned = learn_product(fs, lo).learned;
      v[k].learned.matched = kernels;
    } catch (const Error&) {
      // Too few band extremes: timed with fixed thresholds.
    }
  }
  std::vector<double> ms[kVariants];
  constexpr int kRounds = 5;
  for (int round = 0; round < kRounds; ++round)
    for (int k = 0; k < kVariants; ++k) {
      const auto t0 = clk::now();
      for (const FilletImage& im : imgs) inspect_fillet(im, v[k], false);
      ms[k].push_back(1e3 * std::chrono::duration<double>(clk::now() - t0).count() /
                      double(imgs.size()));
    }
  std::printf(
      "\ninspection of the same %zu fillets, ms per fillet (median of %d alternating rounds):\n",
      imgs.size(), kRounds);
  double base = 0;
  for (int k = 0; k < kVariants; ++k) {
    std::sort(ms[k].begin(), ms[k].end());
    const double m = ms[k][ms[k].size() / 2];
    if (k == 0) base = m;
    std::printf("  %-44s %8.2f  (%.2fx)\n", names[k], m, base > 0 ? m / base : 0.0);
  }
  bench_server_heap(imgs, v[7]);
}

}  // namespace

int bench_path(const PlantConfig& plant, const PathBenchOptions& opt) {
  if (opt.lines < 64) fail("--lines must be >= 64 (got ", opt.lines, ")");
  if (opt.batch < 1) fail("--batch must be >= 1");
  const LaneConfig& lc = plant.lanes.front();
  std::printf("rendering %d lines of a simulated lane ...\n", opt.lines);
  std::fflush(stdout);
  const Recorded rec = render(lc, opt.lines);
  const int grid = lc.fusion.grid_samples;
  const double gbs = read_bandwidth(rec);
  const double bound = gbs * 1e9 / (2.0 * double(rec.frame()));
  std::printf(
      "the whole line path on the CPU, %d lines per lane (%.0f MB of frames), batches of %d "
      "lines;\nread bound: one core reads %.2f GB/s, %.0f lines/s of 2 x %dx%d frames\n",
      rec.lines, double(rec.frames.size()) / 1e6, opt.batch, gbs, bound, rec.width, rec.height);
  std::vector<double> one_core;
  for (int lanes : opt.lanes) {
    const PathTimes t = run_lanes(lc, rec, 0, lanes, opt.batch);
    char title[64];
    std::snprintf(title, sizeof title, "%d lane%s", lanes, lanes > 1 ? "s" : "");
    report(title, t, rec, grid, gbs);
    one_core.push_back(double(t.lines) / t.wall);
  }
  bench_inspection(lc, rec, opt.batch);
  if (opt.threads > 1) {
    std::printf("\nscaling: the lanes split over %d threads, wall-clock lines/s against one\n",
                opt.threads);
    for (size_t i = 0; i < opt.lanes.size(); ++i) {
      const int lanes = opt.lanes[i];
      if (lanes < opt.threads) continue;
      std::vector<PathTimes> parts(opt.threads);
      std::vector<std::thread> pool;
      const auto t0 = clk::now();
      for (int k = 0; k < opt.threads; ++k) {
        const int first = lanes * k / opt.threads, last = lanes * (k + 1) / opt.threads;
        pool.emplace_back(
            [&, k, first, last] { parts[k] = run_lanes(lc, rec, first, last - first, opt.batch); });
      }
      for (auto& th : pool) th.join();
      const double wall = std::chrono::duration<double>(clk::now() - t0).count();
      PathTimes sum;
      for (const PathTimes& p : parts) sum.add(p);
      const double lps = double(sum.lines) / wall;
      std::printf("  %2d lanes: %.0f lines/s on %d threads, %.0f on one: %.2fx\n", lanes, lps,
                  opt.threads, one_core[i], lps / one_core[i]);
    }
  }
  return 0;
}

}  // namespace rangex::cli
