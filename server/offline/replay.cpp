#include "offline/replay.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#include "core/error.h"
#include "offline/line_path.h"

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
    if (lc.xray.energies != info.xray_energies)
      fail("lane ", id, ": recording has ", info.xray_energies,
           " X-ray energies but the plant configuration says ", lc.xray.energies,
           " (xray.energies)");
    if (opt.method) lc.stripe.method = *opt.method;
    configs.push_back(lc);
  }
  // One line path for every lane replayed, as the server runs its lanes.
  LinePath path(configs, opt.backend);
  if (backend_info) *backend_info = path.backend();
  std::vector<LaneReplay> out;
  std::vector<QueuedLine> block;
  for (size_t slot = 0; slot < lanes.size(); ++slot) {
    const int id = lanes[slot];
    const LaneConfig& lc = configs[slot];
    LaneReplay r;
    r.lane = id;
    r.lines = info.lines;
    r.width = info.width;
    r.pixels = info.xray_pixels;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    if (!opt.missing_lines_ok) {
      r.thickness.assign(size_t(r.lines) * r.pixels, nan);
      for (auto& s : r.stripe_rows) s.assign(size_t(r.lines) * r.width, nan);
    }
    const int delay = lc.xray.delay_lines;
    int64_t first_encoder = 0;
    // Keep what the evaluation and the images need: stripe rows per camera line and the
    // thickness registered to X-ray line n + delay.
    const LinePath::Observer observe = [&](const std::vector<QueuedLine>& lines,
                                           const LineResults& res) {
      if (opt.missing_lines_ok) return;  // lines are not where their counts say
      for (size_t k = 0; k < lines.size(); ++k) {
        const int64_t n = lines[k].line.encoder - first_encoder;
        for (int c = 0; c < 2; ++c)
          std::copy_n(&res.stripes.row[(2 * k + c) * size_t(r.width)], r.width,
                      &r.stripe_rows[c][size_t(n) * r.width]);
        const int64_t xl = n + delay;
        if (xl >= r.lines) continue;
        for (int i = 0; i < r.pixels; ++i) {
          const size_t o = k * size_t(r.pixels) + i;
          r.thickness[size_t(xl) * r.pixels + i] = res.thickness_valid[o] ? res.thickness[o] : nan;
        }
      }
    };
    LaneProcessor proc(lc, {opt.baseline, opt.keep_images},
                       [&](InspectedFillet&& f) { r.fillets.push_back(std::move(f)); });
    path.attach(id, &proc);
    const size_t frame = size_t(info.width) * info.height;
    // The frames stay where the page cache has them until they are read into the lines.
    const RecordingReader::MappedFrames frames = rec.map_frames(id);
    std::vector<uint16_t> xray, xray_high;
    std::vector<int64_t> enc;
    const bool dual = info.xray_energies == 2;
    int64_t last_encoder = std::numeric_limits<int64_t>::min();
    const double stages_before = path.stage_seconds();
    for (int64_t n0 = 0; n0 < info.lines; n0 += opt.batch_lines) {
      const int count = int(std::min<int64_t>(opt.batch_lines, info.lines - n0));
      xray.resize(size_t(info.xray_pixels) * count);
      enc.resize(count);
      rec.read(id, n0, count, nullptr, nullptr, xray.data(), enc.data());
      if (dual) {
        xray_high.resize(xray.size());
        rec.read_high(id, n0, count, xray_high.data());
      }
      for (int k = 0; k < count; ++k) {
        if (enc[k] <= last_encoder)
          fail("lane ", id, ": encoder count ", enc[k], " at line ", n0 + k,
               enc[k] == last_encoder ? " repeats the previous line" : " goes backwards");
        if (!opt.missing_lines_ok && last_encoder != std::numeric_limits<int64_t>::min() &&
            enc[k] != last_encoder + 1)
          fail("lane ", id, ": encoder jumps from ", last_encoder, " to ", enc[k], " at line ",
               n0 + k, " (lines are missing)");
        last_encoder = enc[k];
      }
      if (n0 == 0) first_encoder = enc[0];
      // Each line as the server receives it: its bytes, then one copy into the staging.
      shape_block(block, count, id, frame, info.xray_pixels);
      for (int k = 0; k < count; ++k) {
        IncomingLine& in = block[k].line;
        in.encoder = enc[k];
        std::copy_n(frames.frame(0, n0 + k), frame, in.cam0.data());
        std::copy_n(frames.frame(1, n0 + k), frame, in.cam1.data());
        std::memcpy(in.xray.data(), &xray[size_t(info.xray_pixels) * k], in.xray.size());
        if (dual)
          in.xray_high.assign(
              reinterpret_cast<const char*>(&xray_high[size_t(info.xray_pixels) * k]),
              in.xray.size());
        else
          in.xray_high.resize(0);
      }
      path.run(block, observe);
      done += count;
      if (progress) progress(done, total);
    }
    proc.finish();
    r.seconds = path.stage_seconds() - stages_before;
    r.fusion = path.fusion(id);
    r.assembly = proc.assembly();
    r.inspection_seconds = proc.inspection_seconds();
    out.push_back(std::move(r));
  }
  return out;
}

}  // namespace rangex
