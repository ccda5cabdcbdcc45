// calib scatter: the scattering constants K1, K2 per camera from a recording with truth
// (offline/scatter_from_truth.h), printed and, with --out, written into a lane calibration.
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "args.h"
#include "calib/lane_calibration_file.h"
#include "calib/scatter_from_truth.h"
#include "commands.h"
#include "core/error.h"
#include "core/recording.h"

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
  const PlantConfig plant = load_config(a.get("config", ""));
  ScatterFromTruthOptions opt;
  opt.lines = std::min<int64_t>(a.integer("lines", info.lines), info.lines);
  opt.min_height_mm = std::stod(a.get("min-height-mm", "1.0"));
  std::printf("# scattering constants from %s (%lld lines per lane)\n", rec.dir().c_str(),
              (long long)opt.lines);
  std::vector<LaneConfig> lanes;
  for (int lane : info.lanes)
    lanes.push_back(load_lane_calibration(plant, lane, a.get("calibration", "")));
  // With --out (or --calibration) the constants go into that lane calibration, with a report.
  const bool save = a.has("out") || a.has("calibration");
  const int out_lane = int(a.integer("lane", info.lanes.at(0)));
  LaneConfig saved = load_lane_calibration(plant, out_lane, a.get("calibration", ""));
  const std::string out_file = a.get("out", a.get("calibration", ""));
  for (int cam = 0; cam < 2; ++cam) {
    const ScatterFit f = fit_scatter_from_truth(rec, cam, lanes, opt);
    std::printf("cam%d:  scatter: {k1: %.5f, k2: %.5f, k2_offset: %.5f}\n", cam, f.constants.k1,
                f.constants.k2, f.constants.k2_offset);
    std::printf("#   %zu columns; mean |error| px: centroid %.4f, shifted %.4f, modified %.4f\n",
                f.samples, f.centroid_mae_px, f.shifted_mae_px, f.modified_mae_px);
    if (!save) continue;
    const SolveReport r = apply_scatter_fit(saved, cam, f,
                                            "calib scatter on " + fs::absolute(rec.dir()).string() +
                                                " (" + std::to_string(f.samples) + " columns)");
    save_lane_calibration(saved, out_file, r);
  }
  if (save) std::printf("# written to %s\n", out_file.c_str());
  return 0;
}

}  // namespace rangex::cli
