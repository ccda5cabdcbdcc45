// calib scatter: the scattering constants K1, K2 per camera (seed §5.4.2), fitted from a
// recording with truth, where the simulator's true stripe stands in for the coated
// reference profiles of the dissertation.
#include <cmath>
#include <cstdio>

#include "args.h"
#include "calib/scatter_constants.h"
#include "commands.h"
#include "core/error.h"
#include "core/recording.h"
#include "pipeline/stripe_extract.h"
#include "truth_heights.h"

namespace rangex::cli {

int cmd_calib(int argc, char** argv) {
  if (argc < 3)
    fail(
        "usage: calib simulate|camera|staircase|xray|registration|validate|scatter|upload|"
        "list|activate ...");
  if (const int r = cmd_calib_solve(argc, argv); r >= 0) return r;
  if (std::string(argv[2]) != "scatter") return cmd_calib_remote(argc, argv);
  const Args a(argc, argv, 3, {}, {"lines", "config", "min-height-mm"});
  a.expect_positionals(1, "calib scatter DIR [--lines N]");
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
  for (int cam = 0; cam < 2; ++cam) {
    std::vector<float> ref, cen, asym;
    for (int lane : info.lanes) {
      const LaneConfig& lc = plant.lane(lane);
      StripeSlot slot{lc.stripe, {}};
      slot.params.method = StripeMethod::kCentroid;
      const auto truth = rec.truth_f32(lane, "stripe_cam" + std::to_string(cam) + ".f32", W);
      std::vector<float> tz;
      std::vector<uint8_t> tv2;
      TruthHeights(lc, cam).heights(truth, W, tz, tv2);
      std::vector<uint8_t> frames(frame * 64);
      std::vector<int> slots(64, 0);
      StripeOutput so;
      for (int64_t n0 = 0; n0 < lines; n0 += 64) {
        const int count = int(std::min<int64_t>(64, lines - n0));
        rec.read(lane, n0, count, cam == 0 ? frames.data() : nullptr,
                 cam == 1 ? frames.data() : nullptr, nullptr, nullptr);
        extract_stripes(frames.data(), count, W, H, slots.data(), &slot, so);
        for (size_t i = 0; i < size_t(count) * W; ++i) {
          if (!so.valid[i] || !tv2[size_t(n0) * W + i] || !(tz[size_t(n0) * W + i] > min_height))
            continue;
          ref.push_back(truth[size_t(n0) * W + i]);
          cen.push_back(so.centroid[i]);
          asym.push_back(so.asym[i]);
        }
      }
    }
    const ScatterFit f = fit_scatter_constants(ref.data(), cen.data(), asym.data(), ref.size());
    std::printf("cam%d:  scatter: {k1: %.5f, k2: %.5f, k2_offset: %.5f}\n", cam, f.constants.k1,
                f.constants.k2, f.constants.k2_offset);
    std::printf("#   %zu columns; mean |error| px: centroid %.4f, shifted %.4f, modified %.4f\n",
                f.samples, f.centroid_mae_px, f.shifted_mae_px, f.modified_mae_px);
  }
  return 0;
}

}  // namespace rangex::cli
