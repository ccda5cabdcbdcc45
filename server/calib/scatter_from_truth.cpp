#include "calib/scatter_from_truth.h"

#include <algorithm>

#include "calib/scatter_samples.h"
#include "core/error.h"
#include "pipeline/truth_heights.h"

namespace rangex {

ScatterFit fit_scatter_from_truth(const RecordingReader& rec, int cam,
                                  const std::vector<LaneConfig>& lanes,
                                  const ScatterFromTruthOptions& opt) {
  const RecordingInfo& info = rec.info();
  if (!info.has_truth) fail(rec.dir(), " has no truth/: scattering constants need reference rows");
  if (lanes.size() != info.lanes.size())
    fail("scattering constants: ", lanes.size(), " lane calibrations for ", info.lanes.size(),
         " recorded lanes");
  const int64_t lines = opt.lines > 0 ? std::min(opt.lines, info.lines) : info.lines;
  const int W = info.width, H = info.height;
  const size_t frame = size_t(W) * H;
  ScatterSamples samples;
  for (size_t i = 0; i < lanes.size(); ++i) {
    const int lane = info.lanes[i];
    const LaneConfig& lc = lanes[i];
    const auto truth = rec.truth_f32(lane, "stripe_cam" + std::to_string(cam) + ".f32", W);
    std::vector<float> tz;
    std::vector<uint8_t> tv;
    TruthHeights(lc, cam).heights(truth, W, tz, tv);
    for (size_t k = 0; k < tz.size(); ++k) tv[k] = tv[k] && tz[k] > opt.min_height_mm;
    std::vector<uint8_t> frames(frame * 64);
    for (int64_t n0 = 0; n0 < lines; n0 += 64) {
      const int count = int(std::min<int64_t>(64, lines - n0));
      rec.read(lane, n0, count, cam == 0 ? frames.data() : nullptr,
               cam == 1 ? frames.data() : nullptr, nullptr, nullptr);
      add_scatter_samples(frames.data(), count, W, H, lc.stripe, &truth[size_t(n0) * W],
                          &tv[size_t(n0) * W], samples);
    }
  }
  return samples.fit();
}

SolveReport apply_scatter_fit(LaneConfig& lane, int cam, const ScatterFit& f,
                              const std::string& fitted_on) {
  lane.cameras[cam].scatter = f.constants;
  lane.cameras[cam].scatter_fitted_on = fitted_on;
  SolveReport r;
  r.solver = "scatter";
  r.subject = "lane " + std::to_string(lane.id) + " cam" + std::to_string(cam);
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
  return r;
}

}  // namespace rangex
