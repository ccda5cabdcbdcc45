// bench: stripe extraction on 640x200 Mono8 frames, frames/s and GB/s, beside two baselines
// measured in the same run on the same frames: a single-thread sequential read (the
// bandwidth ceiling) and the plain centroid composed from OpenCV calls (cv::threshold,
// cv::reduce), which is what a user would write without rangex.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>
#include <vector>

#include "args.h"
#include "backend_args.h"
#include "bench/bench_backends.h"
#include "bench/bench_commands.h"
#include "bench/bench_path.h"
#include "bench/naive_inspection.h"
#include "commands.h"
#include "core/error.h"
#include "offline/dual_energy_work.h"
#include "pipeline/inspection.h"
#include "pipeline/stripe_extract.h"
#include "sim/plant_simulator.h"
#include "sim/synthetic_fillet.h"

namespace rangex::cli {

namespace {
template <typename F>
double frames_per_second(int frames, double min_seconds, F&& pass) {
  using clk = std::chrono::steady_clock;
  pass();  // warm up
  int passes = 0;
  const auto t0 = clk::now();
  double el = 0;
  do {
    pass();
    ++passes;
    el = std::chrono::duration<double>(clk::now() - t0).count();
  } while (el < min_seconds);
  return double(frames) * passes / el;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Throughputs of several passes measured in alternating rounds, so that a slow spell of a
// shared machine (other tenants, memory traffic) lands on all of them alike; each pass's
// ratio to the first is taken within a round, and the medians are reported.
struct Rounds {
  std::vector<std::vector<double>> fps;  // [pass][round]
  double fps_median(size_t k) const { return median(fps[k]); }
  std::vector<double> ratios(size_t k, size_t base) const {
    std::vector<double> r;
    for (size_t i = 0; i < fps[k].size(); ++i) r.push_back(fps[k][i] / fps[base][i]);
    return r;
  }
  double ratio_median(size_t k, size_t base) const { return median(ratios(k, base)); }
  std::pair<double, double> ratio_range(size_t k, size_t base) const {
    const std::vector<double> r = ratios(k, base);
    const auto [lo, hi] = std::minmax_element(r.begin(), r.end());
    return {*lo, *hi};
  }
};

Rounds measure_rounds(int frames, int rounds, double seconds,
                      const std::vector<std::function<void()>>& passes) {
  Rounds r;
  r.fps.resize(passes.size());
  const double per = seconds / (rounds * double(passes.size()));
  for (int i = 0; i < rounds; ++i)
    for (size_t k = 0; k < passes.size(); ++k)
      r.fps[k].push_back(frames_per_second(frames, per, passes[k]));
  return r;
}
// Stripe extraction over simulated frames, beside a sequential read of the same frames and
// the OpenCV-composed centroid, in alternating rounds.
void bench_stripes(const LaneConfig& lc, int nframes, double secs, int nrounds) {
  const int W = lc.frame_width, H = lc.frame_height;
  const size_t frame = size_t(W) * H;

  // Realistic frames: a simulated lane with fillets, both cameras, distinct lines.
  sim::SimulationParams sp;
  sp.scene.fillets = 2;
  sp.scene.lead_in_mm = 5;
  const sim::LaneSimulator sim(lc, sp);
  std::vector<uint8_t> frames(frame * nframes);
  std::vector<uint16_t> xray(lc.xray.pixels);
  const int rendered = std::min(nframes / 2, 64);
  for (int k = 0; k < rendered; ++k)
    sim.render(int64_t(k) * std::max<int64_t>(1, sim.lines() / rendered), &frames[frame * 2 * k],
               &frames[frame * (2 * k + 1)], xray.data(), nullptr, nullptr, nullptr);
  for (int f = 2 * rendered; f < nframes; ++f)  // the working set exceeds the caches
    std::memcpy(&frames[frame * f], &frames[frame * (f % (2 * rendered))], frame);

  const double bytes = double(frame);
  volatile uint64_t sink = 0;
  const auto read_pass = [&] {
    const uint64_t* p = reinterpret_cast<const uint64_t*>(frames.data());
    const size_t n = frames.size() / 8;
    uint64_t s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    for (size_t i = 0; i + 3 < n; i += 4) {
      s0 += p[i];
      s1 += p[i + 1];
      s2 += p[i + 2];
      s3 += p[i + 3];
    }
    sink = sink + s0 + s1 + s2 + s3;
  };
  StripeSlot slot{lc.stripe, lc.cameras[0].scatter}, centroid_slot = slot;
  centroid_slot.params.method = StripeMethod::kCentroid;
  std::vector<int> slots(nframes, 0);
  StripeOutput so;
  const int threads = int(std::max(1u, std::thread::hardware_concurrency()));
  enum { kRead, kOurs, kCentroid, kOursMt };
  const Rounds rounds = measure_rounds(
      nframes, nrounds, 4 * secs,
      {read_pass, [&] { extract_stripes(frames.data(), nframes, W, H, slots.data(), &slot, so); },
       [&] { extract_stripes(frames.data(), nframes, W, H, slots.data(), &centroid_slot, so); },
       [&] { extract_stripes(frames.data(), nframes, W, H, slots.data(), &slot, so, threads); }});

  cv::setNumThreads(1);
  cv::Mat rowidx(H, W, CV_32F);
  for (int y = 0; y < H; ++y) rowidx.row(y).setTo(float(y));
  cv::Mat f32, thr, sum_g, sum_yg, weighted, peak, centroid;
  const double cv_fps = frames_per_second(nframes, secs, [&] {
    for (int i = 0; i < nframes; ++i) {
      const cv::Mat img(H, W, CV_8U, &frames[frame * i]);
      cv::reduce(img, peak, 0, cv::REDUCE_MAX);
      img.convertTo(f32, CV_32F);
      cv::threshold(f32, thr, lc.stripe.min_peak * lc.stripe.threshold_rel, 0, cv::THRESH_TOZERO);
      cv::reduce(thr, sum_g, 0, cv::REDUCE_SUM, CV_32F);
      cv::multiply(thr, rowidx, weighted);
      cv::reduce(weighted, sum_yg, 0, cv::REDUCE_SUM, CV_32F);
      cv::divide(sum_yg, sum_g, centroid);
    }
  });

  const double read_fps = rounds.fps_median(kRead);
  auto line = [&](const char* name, double fps, double ratio) {
    std::printf("%-38s %10.0f frames/s %7.2f GB/s   %.2fx\n", name, fps, fps * bytes / 1e9, ratio);
  };
  auto pass_line = [&](const char* name, int k) {
    const auto [lo, hi] = rounds.ratio_range(k, kRead);
    std::printf("%-38s %10.0f frames/s %7.2f GB/s   %.2fx  (rounds %.2f-%.2f)\n", name,
                rounds.fps_median(k), rounds.fps_median(k) * bytes / 1e9,
                rounds.ratio_median(k, kRead), lo, hi);
  };
  std::printf(
      "stripe extraction, %dx%d Mono8, %d frames (%.1f MB working set), 1 thread unless stated;\n"
      "medians of %d alternating rounds, ratios taken within each round\n",
      W, H, nframes, double(frames.size()) / 1e6, nrounds);
  std::printf("%-38s %17s %12s   %s\n", "", "", "", "ratio to read");
  line("sequential read (baseline)", read_fps, 1.0);
  line("OpenCV composed centroid (baseline)", cv_fps, cv_fps / read_fps);
  pass_line("rangex modified centroid (default)", kOurs);
  pass_line("rangex plain centroid", kCentroid);
  char mt[64];
  std::snprintf(mt, sizeof mt, "rangex modified centroid, %d threads", threads);
  pass_line(mt, kOursMt);
  std::printf("rangex default / OpenCV composed: %.2fx\n", rounds.fps_median(kOurs) / cv_fps);
}

// Returns the fillet, which bench_dual_energy inspects too.
FilletImage bench_inspection(const LaneConfig& lc, double secs) {
  // Compensation + detection of one 500 x 250 px fillet (200 x 100 mm), beside the same
  // steps written naively, on the same fillet in the same run.
  const FilletImage fillet = sim::synthetic_fillet(
      std::log(3600.0), -0.03, {{-10, 150, 1.5, 0.12}, {20, 230, 3.0, 0.08}}, 7, 500, 250);
  const InspectionParams ip = lc.inspection;
  Decision d_fast = Decision::kPass, d_naive = Decision::kPass;
  const double fast_per_s =
      frames_per_second(1, secs, [&] { d_fast = inspect_fillet(fillet, ip, false).decision; });
  const double naive_per_s =
      frames_per_second(1, secs, [&] { d_naive = inspect_fillet_naive(fillet, ip).decision; });
  std::printf("\ncompensation + detection, one 500x250 px fillet (%d fillet pixels), 1 thread\n",
              fillet.mask_pixels());
  std::printf("%-38s %10.2f ms/fillet  (%s)\n", "naive (baseline)", 1e3 / naive_per_s,
              std::string(decision_name(d_naive)).c_str());
  std::printf("%-38s %10.2f ms/fillet  (%s)  %.1fx faster\n", "rangex", 1e3 / fast_per_s,
              std::string(decision_name(d_fast)).c_str(), fast_per_s / naive_per_s);
  return fillet;
}

void bench_dual_energy(const FilletImage& fillet, const InspectionParams& ip, double secs) {
  // Dual energy (docs/dual-energy.md): the same fillet's thickness on a sandwich detector
  // (lean with 8 % fat, both lines rendered through NIST's coefficients, the wedge fitted),
  // inspected on its bone image, beside one energy on its low line, in the same run. On the
  // CPU, as the server's inspections run; the kernels' cost is in `bench --backend`.
  const DualEnergyCalibrated cal = calibrate_dual_energy(20000);
  const sim::DualEnergyRenderer& det = cal.detector;
  FilletImage dual = fillet;
  dual.has_dual_energy = true;
  dual.dual_energy = cal.params;
  dual.xray_high.resize(dual.size());
  sim::Rng rng(7, 0xde);
  for (size_t i = 0; i < dual.size(); ++i) {
    const double t = std::isfinite(dual.thickness[i]) ? dual.thickness[i] : 0.0;
    sim::RayMaterials m;
    m.lean = 0.92 * t, m.fat = 0.08 * t;
    double lo, hi, vlo, vhi;
    det.mean(m, &lo, &hi, &vlo, &vhi);
    sim::DualEnergyRenderer::draw(lo, hi, vlo, vhi, rng, &dual.xray[i], &dual.xray_high[i]);
  }
  InspectionParams low_line = ip;
  low_line.dual_energy = DualEnergyMethod::kLowLine;
  InspectionParams both = ip;
  both.dual_energy = DualEnergyMethod::kLaserAndLowLine;
  Decision d_low = Decision::kPass, d_dual = Decision::kPass, d_both = Decision::kPass;
  const double low_per_s =
      frames_per_second(1, secs, [&] { d_low = inspect_fillet(dual, low_line, false).decision; });
  const double dual_per_s =
      frames_per_second(1, secs, [&] { d_dual = inspect_fillet(dual, ip, false).decision; });
  const double both_per_s =
      frames_per_second(1, secs, [&] { d_both = inspect_fillet(dual, both, false).decision; });
  std::printf("\ndual energy, the same fillet on a sandwich detector (%d lines), 1 thread, CPU\n",
              dual.rows);
  std::printf("%-38s %10.2f ms/fillet %8.1f us/line  (%s)\n", "one energy, the low line",
              1e3 / low_per_s, 1e6 / low_per_s / dual.rows,
              std::string(decision_name(d_low)).c_str());
  std::printf("%-38s %10.2f ms/fillet %8.1f us/line  (%s)  %.2fx one energy's time\n",
              "dual energy with the laser", 1e3 / dual_per_s, 1e6 / dual_per_s / dual.rows,
              std::string(decision_name(d_dual)).c_str(), low_per_s / dual_per_s);
  std::printf("%-38s %10.2f ms/fillet %8.1f us/line  (%s)  %.2fx one energy's time\n",
              "dual energy with the laser + low line", 1e3 / both_per_s,
              1e6 / both_per_s / dual.rows, std::string(decision_name(d_both)).c_str(),
              low_per_s / both_per_s);
}

}  // namespace

int cmd_bench(int argc, char** argv) {
  const Args a(argc, argv, 2, {"path"},
               {"frames", "seconds", "rounds", "config", "backend", "device", "threads", "lanes",
                "batches", "lines", "batch"});
  a.expect_positionals(0,
                       "bench [--frames N] [--seconds S] [--rounds R] | bench --backend "
                       "cpu|opencl|vulkan|all [--device D] [--seconds S] [--lanes 1,4,16] "
                       "[--batches 1,16,64,256] | bench --path [--lanes 1,4,16] [--lines N] "
                       "[--batch B] [--threads T]");
  if (a.flag("path")) {
    PathBenchOptions o;
    o.lanes = a.int_list("lanes", o.lanes, 4096);
    o.lines = int(a.integer("lines", o.lines));
    o.batch = int(a.integer("batch", o.batch));
    o.threads = int(a.integer("threads", o.threads));
    if (o.threads < 1 || o.threads > 64) fail("--threads must be within 1..64");
    return bench_path(load_config(a.get("config", "")), o);
  }
  if (a.has("backend")) {
    BackendBenchOptions o;
    o.backends = backend_names(a.get("backend", "all"));
    // The CPU first, always: every other backend is reported as a ratio to it.
    o.backends.erase(std::remove(o.backends.begin(), o.backends.end(), "cpu"), o.backends.end());
    o.backends.insert(o.backends.begin(), "cpu");
    o.device = a.get("device", "");
    o.threads = int(a.integer("threads", long(std::max(1u, std::thread::hardware_concurrency()))));
    if (o.threads < 1) fail("--threads must be >= 1");
    o.seconds = std::stod(a.get("seconds", "0.25"));
    if (!(o.seconds > 0)) fail("--seconds must be > 0");
    o.lanes = a.int_list("lanes", o.lanes, 4096);
    o.batches = a.int_list("batches", o.batches, 4096);
    return bench_backends(load_config(a.get("config", "")), o);
  }
  const int nframes = int(a.integer("frames", 256));
  const double secs = std::stod(a.get("seconds", "1.0"));
  const int nrounds = int(a.integer("rounds", 9));
  if (nframes < 2) fail("--frames must be >= 2");
  if (nrounds < 1) fail("--rounds must be >= 1");
  if (!(secs > 0)) fail("--seconds must be > 0");
  const PlantConfig plant = load_config(a.get("config", ""));
  const LaneConfig& lc = plant.lanes.front();
  bench_stripes(lc, nframes, secs, nrounds);
  const FilletImage fillet = bench_inspection(lc, secs);
  bench_dual_energy(fillet, lc.inspection, secs);
  return 0;
}

}  // namespace rangex::cli
