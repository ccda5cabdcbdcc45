// bench: stripe extraction on 640x200 Mono8 frames, frames/s and GB/s, beside two baselines
// measured in the same run on the same frames: a single-thread sequential read (the
// bandwidth ceiling) and the plain centroid composed from OpenCV calls (cv::threshold,
// cv::reduce), which is what a user would write without rangex.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "naive_inspection.h"
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
}  // namespace

int cmd_bench(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, {"frames", "seconds", "config"});
  a.expect_positionals(0, "bench [--frames N] [--seconds S]");
  const int nframes = int(a.integer("frames", 256));
  const double secs = std::stod(a.get("seconds", "1.0"));
  if (nframes < 2) fail("--frames must be >= 2");
  const PlantConfig plant = load_config(a.get("config", ""));
  const LaneConfig& lc = plant.lanes.front();
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
  const double read_fps = frames_per_second(nframes, secs, [&] {
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
  });

  StripeSlot slot{lc.stripe, lc.cameras[0].scatter};
  std::vector<int> slots(nframes, 0);
  StripeOutput so;
  const double ours_fps = frames_per_second(nframes, secs, [&] {
    extract_stripes(frames.data(), nframes, W, H, slots.data(), &slot, so);
  });
  const int threads = int(std::max(1u, std::thread::hardware_concurrency()));
  const double ours_mt_fps = frames_per_second(nframes, secs, [&] {
    extract_stripes(frames.data(), nframes, W, H, slots.data(), &slot, so, threads);
  });
  slot.params.method = StripeMethod::kCentroid;
  const double ours_centroid_fps = frames_per_second(nframes, secs, [&] {
    extract_stripes(frames.data(), nframes, W, H, slots.data(), &slot, so);
  });

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

  auto line = [&](const char* name, double fps, double ref) {
    std::printf("%-38s %10.0f frames/s %7.2f GB/s   %.2fx\n", name, fps, fps * bytes / 1e9,
                fps / ref);
  };
  std::printf(
      "stripe extraction, %dx%d Mono8, %d frames (%.1f MB working set), 1 thread unless stated\n",
      W, H, nframes, double(frames.size()) / 1e6);
  std::printf("%-38s %17s %12s   %s\n", "", "", "", "ratio to read");
  line("sequential read (baseline)", read_fps, read_fps);
  line("OpenCV composed centroid (baseline)", cv_fps, read_fps);
  line("rangex modified centroid (default)", ours_fps, read_fps);
  line("rangex plain centroid", ours_centroid_fps, read_fps);
  char mt[64];
  std::snprintf(mt, sizeof mt, "rangex modified centroid, %d threads", threads);
  line(mt, ours_mt_fps, read_fps);
  std::printf("rangex default / OpenCV composed: %.2fx\n", ours_fps / cv_fps);

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
  return 0;
}

}  // namespace rangex::cli
