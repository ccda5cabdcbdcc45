// calib scatter: the scattering constants K1, K2 per camera (Laser Range Imaging §5.4.2), fitted
// from a recording with truth, where the simulator's true stripe stands in for the coated reference
// profiles of the dissertation.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "args.h"
#include "calib/scatter_samples.h"
#include "calib_rig.h"
#include "commands.h"
#include "core/error.h"
#include "core/recording.h"
#include "truth_heights.h"

namespace fs = std::filesystem;

namespace rangex::cli {

int cmd_calib(int argc, char** argv) {
  if (argc < 3)
    fail(
        "usage: calib simulate|camera|staircase|xray|registration|validate|scatter|upload|"
        "list|activate ...");
  if (const int r = cmd_calib_solve(argc, argv); r >= 0) return r;
  if (std::string(argv[2]) != "scatter") return cmd_calib_remote(argc, argv);
  const Args a(argc, argv, 3, {},
               {"lines", "config", "min-height-mm", "lane", "calibration", "out"});
  a.expect_positionals(1, "calib scatter DIR [--lines N] [--calibration F] [--out F]");
  const RecordingReader rec(a.positional(0, "recording folder"));
  const RecordingInfo& info = rec.info();
  if (!info.has_truth) fail(rec.dir(), " has no truth/: scattering constants need reference rows");
  const PlantConfig plant = load_config(a.get("config", ""));
  const int64_t lines = std::min<int64_t>(a.integer("lines", info.lines), info.lines);
  // The constants describe scattering in meat: only columns whose reference point lies on
  // the fillet (above this height) take part; the belt barely scatters.
  const double min_height = std::stod(a.get("min-height-mm", "1.0"));
  const int W = info.width, H = info.height;
  const size_t frame = size_t(W) * H;
  std::printf("# scattering constants from %s (%lld lines per lane)\n", rec.dir().c_str(),
              (long long)lines);
  // With --out (or --calibration) the constants go into that lane calibration, with a report.
  const bool save = a.has("out") || a.has("calibration");
  const int out_lane = int(a.integer("lane", info.lanes.at(0)));
  LaneConfig saved = load_lane_calibration(plant, out_lane, a.get("calibration", ""));
  const std::string out_file = a.get("out", a.get("calibration", ""));
  for (int cam = 0; cam < 2; ++cam) {
    ScatterSamples samples;
    for (int lane : info.lanes) {
      const LaneConfig lc = load_lane_calibration(plant, lane, a.get("calibration", ""));
      const auto truth = rec.truth_f32(lane, "stripe_cam" + std::to_string(cam) + ".f32", W);
      std::vector<float> tz;
      std::vector<uint8_t> tv;
      TruthHeights(lc, cam).heights(truth, W, tz, tv);
      for (size_t i = 0; i < tz.size(); ++i) tv[i] = tv[i] && tz[i] > min_height;
      std::vector<uint8_t> frames(frame * 64);
      for (int64_t n0 = 0; n0 < lines; n0 += 64) {
        const int count = int(std::min<int64_t>(64, lines - n0));
        rec.read(lane, n0, count, cam == 0 ? frames.data() : nullptr,
                 cam == 1 ? frames.data() : nullptr, nullptr, nullptr);
        add_scatter_samples(frames.data(), count, W, H, lc.stripe, &truth[size_t(n0) * W],
                            &tv[size_t(n0) * W], samples);
      }
    }
    const ScatterFit f = samples.fit();
    std::printf("cam%d:  scatter: {k1: %.5f, k2: %.5f, k2_offset: %.5f}\n", cam, f.constants.k1,
                f.constants.k2, f.constants.k2_offset);
    std::printf("#   %zu columns; mean |error| px: centroid %.4f, shifted %.4f, modified %.4f\n",
                f.samples, f.centroid_mae_px, f.shifted_mae_px, f.modified_mae_px);
    if (!save) continue;
    saved.cameras[cam].scatter = f.constants;
    saved.cameras[cam].scatter_fitted_on = "calib scatter on " + fs::absolute(rec.dir()).string() +
                                           " (" + std::to_string(f.samples) + " columns)";
    SolveReport r;
    r.solver = "scatter";
    r.subject = "lane " + std::to_string(out_lane) + " cam" + std::to_string(cam);
    r.parameters = {{"k1", f.constants.k1, 0, "px"},
                    {"k2", f.constants.k2, 0, "px"},
                    {"k2_offset", f.constants.k2_offset, 0, "px"}};
    r.figures = {{"samples", double(f.samples)},
                 {"centroid_mae_px", f.centroid_mae_px},
                 {"shifted_mae_px", f.shifted_mae_px},
                 {"modified_mae_px", f.modified_mae_px}};
    // The correction must help: a fit that leaves the stripe worse than the plain centroid
    // is not a calibration.
    if (!(f.modified_mae_px < f.centroid_mae_px)) {
      r.passed = false;
      r.failures.push_back("the modified centroid is not better than the plain one");
    }
    save_lane_calibration(saved, out_file, r);
  }
  if (save) std::printf("# written to %s\n", out_file.c_str());
  return 0;
}

}  // namespace rangex::cli
