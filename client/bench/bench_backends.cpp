#include "bench/bench_backends.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <map>
#include <memory>

#include "backends/registry.h"
#include "backends/robust_fit_batch.h"
#include "core/error.h"
#include "offline/stage_cases.h"

namespace rangex::cli {

namespace {

using clk = std::chrono::steady_clock;

struct Cell {
  double per_s = 0;  // batches per second
  StageTimes t;      // mean per batch
};

// Repeats `pass` for `seconds` (at least 3 times, after one warm-up); the backend's own
// split of each pass is averaged.
template <class F>
Cell measure(Backend& b, double seconds, F&& pass) {
  pass();
  Cell c;
  int n = 0;
  const auto t0 = clk::now();
  double el = 0;
  do {
    pass();
    ++n;
    const StageTimes& t = b.last_times();
    c.t.upload += t.upload;
    c.t.compute += t.compute;
    c.t.download += t.download;
    el = std::chrono::duration<double>(clk::now() - t0).count();
  } while (el < seconds || n < 3);
  c.per_s = n / el;
  c.t.upload /= n;
  c.t.compute /= n;
  c.t.download /= n;
  return c;
}

// The line path as the server runs it: fill staging, submit, two batches in flight.
Cell line_path(Backend& b, const LineBatchInputs& batch, double seconds) {
  std::deque<LineBatchSlot*> flight;
  LineResults r;
  const size_t bytes = batch.frames.size();
  auto one = [&] {
    if (flight.size() == 2) {
      b.collect(*flight.front(), r);
      flight.pop_front();
    }
    LineBatchSlot& s = b.acquire(batch.lines);
    std::memcpy(s.frames(), batch.frames.data(), bytes);
    std::copy(batch.lane_slot.begin(), batch.lane_slot.end(), s.lane_slot());
    b.submit(s);
    flight.push_back(&s);
  };
  Cell c = measure(b, seconds, one);
  while (!flight.empty()) {
    b.collect(*flight.front(), r);
    flight.pop_front();
  }
  return c;
}

void print_cell(const char* backend, int lanes, int lines, double items_per_batch,
                double bytes_per_batch, const Cell& c, const Cell* cpu, const char* unit) {
  std::printf("%-12s %5d %6d %12.0f %s %8.2f GB/s %9.3f %9.3f %9.3f ms", backend, lanes, lines,
              c.per_s * items_per_batch, unit, c.per_s * bytes_per_batch / 1e9, 1e3 * c.t.upload,
              1e3 * c.t.compute, 1e3 * c.t.download);
  if (cpu) std::printf("  %6.2fx cpu", c.per_s / cpu->per_s);
  std::printf("\n");
  std::fflush(stdout);
}

// What the tables measured that the closing lines compare, by backend.
struct BenchRates {
  std::map<std::string, double> bandwidth;                          // host-to-device copy, bytes/s
  std::map<std::string, double> best_stripe_bytes;                  // stripe stage, frames' bytes/s
  std::map<std::string, double> best_lines;                         // line path, lines/s
  std::map<std::string, std::map<std::string, double>> stage_rate;  // stage: items/s
};

// Every requested backend that starts, each set to `lanes`, with its copy bandwidth.
std::vector<std::unique_ptr<Backend>> start_backends(const BackendBenchOptions& opt,
                                                     const std::vector<LaneConfig>& lanes,
                                                     BenchRates& rates) {
  std::vector<std::unique_ptr<Backend>> backends;
  for (const std::string& name : opt.backends) {
    BackendRequest r;
    r.name = name;
    r.device = opt.device;
    r.threads = opt.threads;
    try {
      backends.push_back(create_backend(r));
    } catch (const std::exception& e) {
      std::printf("%s: cannot start: %s\n", name.c_str(), e.what());
      continue;
    }
    const BackendInfo& i = backends.back()->info();
    std::printf("%-12s %s; %s; %s%s\n", i.name.c_str(), i.device.c_str(), i.driver.c_str(),
                i.limits.c_str(), i.emulated ? " (a CPU emulation)" : "");
  }
  if (backends.empty()) fail("no backend could start");
  for (auto& b : backends) {
    b->set_lanes(lanes);
    const double bw = b->upload_bandwidth(size_t(256) << 20);
    rates.bandwidth[b->info().name] = bw;
    if (bw > 0)
      std::printf("%-12s host-to-device copy: %.2f GB/s (256 MiB from pinned staging, best of 5)\n",
                  b->info().name.c_str(), bw / 1e9);
  }
  return backends;
}

void print_stripe_table(std::vector<std::unique_ptr<Backend>>& backends, const LaneConfig& lc,
                        const std::vector<uint8_t>& rendered, const BackendBenchOptions& opt,
                        BenchRates& rates) {
  const size_t frame = size_t(lc.frame_width) * lc.frame_height;
  const bool has_cpu = backends.front()->info().name == "cpu";
  std::printf(
      "\nstripe stage: %dx%d Mono8 frames from the backend's staging, both cameras of every line "
      "in one dispatch; per batch: upload / compute / download\n",
      lc.frame_width, lc.frame_height);
  std::printf("%-12s %5s %6s %21s %13s %9s %9s %9s\n", "backend", "lanes", "lines", "frames/s", "",
              "up", "compute", "down");
  std::map<std::pair<int, int>, Cell> cpu_stripes;
  for (int nl : opt.lanes)
    for (int lines : opt.batches) {
      const LineBatchInputs bb = interleave_lines(rendered, frame, nl, lines);
      for (auto& b : backends) {
        // The frames sit in the backend's own staging (pinned on a device), as the server's
        // do: a copy from pageable memory would measure the driver's bounce buffer.
        LineBatchSlot& staging = b->acquire(lines);
        std::memcpy(staging.frames(), bb.frames.data(), bb.frames.size());
        std::copy(bb.lane_slot.begin(), bb.lane_slot.end(), staging.lane_slot());
        StripeOutput so;
        const Cell c = measure(*b, opt.seconds, [&] {
          b->stripes(staging.frames(), 2 * lines, bb.frame_slot.data(), so);
        });
        LineResults done;  // gives the staging slot back
        b->submit(staging);
        b->collect(staging, done);
        const bool is_cpu = b->info().name == "cpu";
        if (is_cpu) cpu_stripes[{nl, lines}] = c;
        const double bytes = double(bb.frames.size());
        double& best = rates.best_stripe_bytes[b->info().name];
        best = std::max(best, c.per_s * bytes);
        print_cell(b->info().name.c_str(), nl, lines, 2.0 * lines, bytes, c,
                   has_cpu && !is_cpu ? &cpu_stripes[{nl, lines}] : nullptr, "frames/s");
      }
    }
}

void print_line_path_table(std::vector<std::unique_ptr<Backend>>& backends, const LaneConfig& lc,
                           const std::vector<uint8_t>& rendered, const BackendBenchOptions& opt,
                           BenchRates& rates) {
  const size_t frame = size_t(lc.frame_width) * lc.frame_height;
  const bool has_cpu = backends.front()->info().name == "cpu";
  std::printf(
      "\nline path: stripes, rectification, fusion, projection; one upload and one download per "
      "batch, two batches in flight\n");
  std::printf("%-12s %5s %6s %21s %13s %9s %9s %9s\n", "backend", "lanes", "lines", "lines/s", "",
              "up", "compute", "down");
  std::map<std::pair<int, int>, Cell> cpu_path;
  for (int nl : opt.lanes)
    for (int lines : opt.batches) {
      const LineBatchInputs bb = interleave_lines(rendered, frame, nl, lines);
      for (auto& b : backends) {
        const Cell c = line_path(*b, bb, opt.seconds);
        double& best = rates.best_lines[b->info().name];
        best = std::max(best, c.per_s * lines);
        const bool is_cpu = b->info().name == "cpu";
        if (is_cpu) cpu_path[{nl, lines}] = c;
        print_cell(b->info().name.c_str(), nl, lines, lines, double(bb.frames.size()), c,
                   has_cpu && !is_cpu ? &cpu_path[{nl, lines}] : nullptr, "lines/s ");
      }
    }
}

// Every case of the stage table (offline/stage_cases.h, which the backend suite checks on
// every backend) on the largest batch and 16 fillets of 60,000 pixels (a 500 x 250 px
// fillet holds about that many); the robust fit beside them.
void print_stage_cases(std::vector<std::unique_ptr<Backend>>& backends, const LaneConfig& lc,
                       const BackendBenchOptions& opt, int max_lanes, BenchRates& rates) {
  const int nl = max_lanes, lines = *std::max_element(opt.batches.begin(), opt.batches.end());
  const StageWork work = make_stage_work(lc, nl, lines, 16, 60000, 60000);
  const std::vector<StageCase> cases = stage_cases(work);
  std::printf("\nstage cases alone, %d lanes, %d lines per batch, %d fillets of %d pixels\n", nl,
              lines, 16, 60000);
  std::printf("%-12s %-12s %14s %-8s %9s %9s %9s\n", "backend", "stage", "items/s", "", "up",
              "compute", "down");
  std::map<std::string, double> cpu_stage;
  const FilletBatch fb = work.fillets();
  for (auto& b : backends) {
    const std::string name = b->info().name;
    b->set_lanes(work.lanes);
    auto row = [&](const std::string& stage, double items, const std::string& unit, const Cell& c) {
      std::printf("%-12s %-12s %14.0f %-8s %9.3f %9.3f %9.3f ms", name.c_str(), stage.c_str(),
                  c.per_s * items, unit.c_str(), 1e3 * c.t.upload, 1e3 * c.t.compute,
                  1e3 * c.t.download);
      if (name == "cpu")
        cpu_stage[stage] = c.per_s;
      else if (cpu_stage.count(stage))
        std::printf("  %6.2fx cpu", c.per_s / cpu_stage[stage]);
      std::printf("\n");
    };
    for (const StageCase& sc : cases) {
      StageOutput out;
      const Cell c = measure(*b, opt.seconds, [&] { sc.run(*b, work, out); });
      rates.stage_rate[name][sc.stage] = c.per_s * sc.items;
      row(sc.stage, sc.items, sc.unit, c);
    }
    // The whole robust fit: every iteration's per-pixel work on the backend, the iteration
    // logic (MAD scale, weighted line, deviance) on the host.
    row("fit", double(fb.pixels()), "pixels",
        measure(*b, opt.seconds, [&] { fit_tukey_lines(*b, fb); }));
  }
}

// Dual energy beside the line stages, per X-ray line: the decomposition (basis and lengths)
// and the bone given the fat share, per line of the detector's pixels, against the line
// path's cost per line at its best batch; then the stripe stage against the copy.
void print_closing_lines(const std::vector<std::unique_ptr<Backend>>& backends,
                         const LaneConfig& lc, BenchRates& rates) {
  std::printf("\ndual energy per X-ray line of %d pixels, beside the line path (best batch):\n",
              lc.xray.pixels);
  std::printf("%-12s %14s %14s %14s\n", "backend", "decomposition", "bone", "line path");
  for (auto& b : backends) {
    const std::string name = b->info().name;
    auto us = [&](double per_s) { return per_s > 0 ? 1e6 / per_s : 0.0; };
    std::printf("%-12s %11.1f us %11.1f us %11.1f us\n", name.c_str(),
                us(rates.stage_rate[name]["dual-energy"] / lc.xray.pixels),
                us(rates.stage_rate[name]["dual-energy-bone"] / lc.xray.pixels),
                us(rates.best_lines[name]));
  }

  std::printf("\nstripe stage at its best batch, against the device's host-to-device copy:\n");
  for (auto& b : backends) {
    const std::string name = b->info().name;
    const double bw = rates.bandwidth[name], best = rates.best_stripe_bytes[name];
    if (bw > 0)
      std::printf("%-12s %.2f GB/s of frames = %.2f of the %.2f GB/s copy bandwidth\n",
                  name.c_str(), best / 1e9, best / bw, bw / 1e9);
    else
      std::printf("%-12s %.2f GB/s of frames (reads host memory in place: no copy to compare)\n",
                  name.c_str(), best / 1e9);
  }
}

}  // namespace

int bench_backends(const PlantConfig& plant, const BackendBenchOptions& opt) {
  const int max_lanes = *std::max_element(opt.lanes.begin(), opt.lanes.end());
  const PlantConfig p = default_plant_config(max_lanes);
  const LaneConfig& lc = plant.lanes.front();
  std::vector<LaneConfig> lanes = p.lanes;
  for (LaneConfig& l : lanes) {
    const int id = l.id;
    l = lc;
    l.id = id;
  }
  // 64 distinct lines of a simulated lane with fillets in it.
  const std::vector<uint8_t> rendered = render_distinct_lines(lc, 64);
  BenchRates rates;
  std::vector<std::unique_ptr<Backend>> backends = start_backends(opt, lanes, rates);
  print_stripe_table(backends, lc, rendered, opt, rates);
  print_line_path_table(backends, lc, rendered, opt, rates);
  print_stage_cases(backends, lc, opt, max_lanes, rates);
  print_closing_lines(backends, lc, rates);
  return 0;
}

}  // namespace rangex::cli
