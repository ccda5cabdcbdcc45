#include "replay.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace rangex {

std::vector<LaneReplay> replay_recording(const RecordingReader& rec, const PlantConfig& plant,
                                         const ReplayOptions& opt, const ReplayProgress& progress,
                                         BackendInfo* backend_info) {
  const RecordingInfo& info = rec.info();
  if (info.calibration_id != plant.calibration_id && !opt.recalibrated)
    fail("calibration mismatch: the recording was made with calibration '", info.calibration_id,
         "' but the plant configuration holds '", plant.calibration_id, "'");
  if (opt.batch_lines <= 0) fail("batch size must be > 0 (got ", opt.batch_lines, ")");
  std::vector<int> lanes = opt.lanes.empty() ? info.lanes : opt.lanes;
  for (int id : lanes)
    if (std::find(info.lanes.begin(), info.lanes.end(), id) == info.lanes.end())
      fail("lane ", id, " is not in the recording (it holds lanes ", info.lanes.size(), ")");

  const int64_t total = info.lines * int64_t(lanes.size());
  int64_t done = 0;
  std::vector<LaneConfig> configs;
  for (int id : lanes) {
    LaneConfig lc = plant.lane(id);
    if (lc.frame_width != info.width || lc.frame_height != info.height)
      fail("lane ", id, ": recording frames are ", info.width, "x", info.height,
           " but the plant configuration says ", lc.frame_width, "x", lc.frame_height);
    if (lc.xray.pixels != info.xray_pixels)
      fail("lane ", id, ": recording X-ray lines have ", info.xray_pixels,
           " pixels but the plant configuration says ", lc.xray.pixels);
    if (std::abs(lc.encoder_step_mm - info.encoder_step_mm) > 1e-9)
      fail("lane ", id, ": recording encoder step is ", info.encoder_step_mm,
           " mm but the plant configuration says ", lc.encoder_step_mm, " mm");
    if (opt.method) lc.stripe.method = *opt.method;
    configs.push_back(lc);
  }
  // One backend for every lane replayed: the lane's slot is its place in `lanes`.
  const std::unique_ptr<Backend> backend = create_backend(opt.backend);
  backend->set_lanes(configs);
  if (backend_info) *backend_info = backend->info();
  std::vector<LaneReplay> out;
  for (size_t slot = 0; slot < lanes.size(); ++slot) {
    const int id = lanes[slot];
    const LaneConfig& lc = configs[slot];
    LaneReplay r;
    r.lane = id;
    r.lines = info.lines;
    r.width = info.width;
    r.pixels = info.xray_pixels;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    r.thickness.assign(size_t(r.lines) * r.pixels, nan);
    for (auto& s : r.stripe_rows) s.assign(size_t(r.lines) * r.width, nan);
    const int delay = lc.xray.delay_lines;
    int64_t first_encoder = 0;
    // Keep what the evaluation and the images need: stripe rows per camera line and the
    // thickness registered to X-ray line n + delay.
    auto observe = [&](const LineResults& res, const int64_t* enc, int count) {
      for (int k = 0; k < count; ++k) {
        const int64_t n = enc[k] - first_encoder;
        for (int c = 0; c < 2; ++c)
          std::copy_n(&res.stripes.row[size_t(2 * k + c) * r.width], r.width,
                      &r.stripe_rows[c][size_t(n) * r.width]);
        const int64_t xl = n + delay;
        if (xl >= r.lines) continue;
        for (int i = 0; i < r.pixels; ++i) {
          const size_t o = size_t(k) * r.pixels + i;
          r.thickness[size_t(xl) * r.pixels + i] = res.thickness_valid[o] ? res.thickness[o] : nan;
        }
      }
    };
    LaneProcessor proc(lc, {opt.baseline, opt.keep_images},
                       [&](InspectedFillet&& f) { r.fillets.push_back(std::move(f)); });
    LineResults res;
    const size_t frame = size_t(info.width) * info.height;
    // The frames stay where the page cache has them until they are copied into staging.
    const RecordingReader::MappedFrames frames = rec.map_frames(id);
    std::vector<uint16_t> xray;
    std::vector<int64_t> enc;
    int64_t last_encoder = std::numeric_limits<int64_t>::min();
    for (int64_t n0 = 0; n0 < info.lines; n0 += opt.batch_lines) {
      const int count = int(std::min<int64_t>(opt.batch_lines, info.lines - n0));
      xray.resize(size_t(info.xray_pixels) * count);
      enc.resize(count);
      rec.read(id, n0, count, nullptr, nullptr, xray.data(), enc.data());
      for (int k = 0; k < count; ++k) {
        if (enc[k] <= last_encoder)
          fail("lane ", id, ": encoder count ", enc[k], " at line ", n0 + k,
               enc[k] == last_encoder ? " repeats the previous line" : " goes backwards");
        if (last_encoder != std::numeric_limits<int64_t>::min() && enc[k] != last_encoder + 1)
          fail("lane ", id, ": encoder jumps from ", last_encoder, " to ", enc[k], " at line ",
               n0 + k, " (lines are missing)");
        last_encoder = enc[k];
      }
      if (n0 == 0) first_encoder = enc[0];
      // Both cameras' frames interleaved straight into the backend's staging.
      const auto t0 = std::chrono::steady_clock::now();
      LineBatchSlot& batch = backend->acquire(count);
      for (int k = 0; k < count; ++k) {
        std::copy_n(frames.frame(0, n0 + k), frame, batch.frames() + frame * (2 * k));
        std::copy_n(frames.frame(1, n0 + k), frame, batch.frames() + frame * (2 * k + 1));
      }
      std::fill_n(batch.lane_slot(), count, int(slot));
      backend->submit(batch);
      backend->collect(batch, res);
      r.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      observe(res, enc.data(), count);
      proc.push(res, 0, count, xray.data(), enc.data());
      done += count;
      if (progress) progress(done, total);
    }
    proc.finish();
    r.fusion = res.fusion;
    r.assembly = proc.assembly();
    r.inspection_seconds = proc.inspection_seconds();
    out.push_back(std::move(r));
  }
  return out;
}

}  // namespace rangex
