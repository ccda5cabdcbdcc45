#include "pipeline/line_pipeline.h"

#include <algorithm>

#include "core/error.h"
#include "pipeline/fan_projection.h"

namespace rangex {

LinePipeline::LinePipeline(std::vector<LaneConfig> lanes, int threads)
    : lanes_(std::move(lanes)), threads_(std::max(1, threads)) {
  if (lanes_.empty()) fail("pipeline needs at least one lane");
  const LaneConfig& first = lanes_.front();
  width_ = first.frame_width;
  height_ = first.frame_height;
  grid_n_ = first.fusion.grid_samples;
  pixels_ = first.xray.pixels;
  for (const LaneConfig& l : lanes_) {
    if (l.frame_width != width_ || l.frame_height != height_ || l.fusion.grid_samples != grid_n_ ||
        l.xray.pixels != pixels_)
      fail("lane ", l.id, " differs in frame size, fusion grid or detector pixels from lane ",
           first.id, "; such lanes run in separate pipelines");
    for (int c = 0; c < 2; ++c) {
      stripe_slots_.push_back({l.stripe, l.cameras[c].scatter});
      tables_.push_back(build_rectify_table(l.cameras[c].model, l.laser, l.lut_step_px));
    }
    fusion_.push_back(l.fusion);
    beams_.push_back(l.xray);
  }
}

int LinePipeline::slot_of(int lane_id) const {
  for (size_t i = 0; i < lanes_.size(); ++i)
    if (lanes_[i].id == lane_id) return int(i);
  fail("unknown lane ", lane_id);
}

void LinePipeline::run(const LineBatch& b, LineResults& out) const {
  const size_t frame = size_t(width_) * height_;
  if (b.frames.size() != size_t(b.lines) * 2 * frame || b.lane_slot.size() != size_t(b.lines))
    fail("line batch of ", b.lines, " lines has ", b.frames.size(), " frame bytes and ",
         b.lane_slot.size(), " lane slots (expected ", size_t(b.lines) * 2 * frame, " and ",
         b.lines, ")");
  std::vector<int> frame_slot(size_t(b.lines) * 2);
  for (int l = 0; l < b.lines; ++l) {
    if (b.lane_slot[l] < 0 || b.lane_slot[l] >= int(lanes_.size()))
      fail("line ", l, " of the batch names lane slot ", b.lane_slot[l], " which does not exist");
    frame_slot[2 * l] = b.lane_slot[l] * 2;
    frame_slot[2 * l + 1] = b.lane_slot[l] * 2 + 1;
  }
  const int frames = b.lines * 2;
  const size_t cols = size_t(frames) * width_;
  extract_stripes(b.frames.data(), frames, width_, height_, frame_slot.data(), stripe_slots_.data(),
                  out.stripes, threads_);
  out.x.resize(cols);
  out.z.resize(cols);
  out.xz_valid.resize(cols);
  rectify(out.stripes.row.data(), out.stripes.valid.data(), frames, width_, frame_slot.data(),
          tables_.data(), out.x.data(), out.z.data(), out.xz_valid.data());
  out.profile.resize(size_t(b.lines) * grid_n_);
  out.profile_valid.resize(out.profile.size());
  fuse_profiles(out.x.data(), out.z.data(), out.xz_valid.data(), width_, b.lines,
                b.lane_slot.data(), fusion_.data(), grid_n_, out.profile.data(),
                out.profile_valid.data(), &out.fusion);
  out.thickness.resize(size_t(b.lines) * pixels_);
  out.thickness_valid.resize(out.thickness.size());
  project_fan_beam(out.profile.data(), out.profile_valid.data(), b.lines, grid_n_,
                   b.lane_slot.data(), fusion_.data(), beams_.data(), pixels_, out.thickness.data(),
                   out.thickness_valid.data());
}

}  // namespace rangex
