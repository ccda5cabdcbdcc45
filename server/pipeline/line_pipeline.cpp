#include "pipeline/line_pipeline.h"

#include <algorithm>

#include "core/error.h"
#include "pipeline/fan_projection.h"

namespace rangex {

LinePipeline::LinePipeline(std::vector<LaneConfig> lanes, int threads, bool vector_blocks)
    : lanes_(std::move(lanes)), threads_(std::max(1, threads)), vector_blocks_(vector_blocks) {
  if (lanes_.empty()) fail("pipeline needs at least one lane");
  const LaneConfig& first = lanes_.front();
  width_ = first.frame_width;
  height_ = first.frame_height;
  grid_n_ = first.fusion.grid_samples;
  pixels_ = first.xray.pixels;
  for (const LaneConfig& l : lanes_) {
    check_shape(l);
    for (int c = 0; c < 2; ++c) {
      stripe_slots_.push_back({l.stripe, l.cameras[c].scatter});
      tables_.push_back(build_rectify_table(l.cameras[c].model, l.laser, l.lut_step_px));
    }
    fusion_.push_back(l.fusion);
    beams_.push_back(l.xray);
    rays_.push_back(build_ray_table(l.xray, l.fusion));
  }
}

void LinePipeline::check_shape(const LaneConfig& l) const {
  if (l.frame_width != width_ || l.frame_height != height_ || l.fusion.grid_samples != grid_n_ ||
      l.xray.pixels != pixels_)
    fail("lane ", l.id, " differs in frame size, fusion grid or detector pixels from lane ",
         lanes_.front().id, "; such lanes run in separate pipelines");
}

void LinePipeline::update_lane(int slot, const LaneConfig& l) {
  if (slot < 0 || slot >= int(lanes_.size())) fail("no lane slot ", slot);
  check_shape(l);
  lanes_[slot] = l;
  for (int c = 0; c < 2; ++c) {
    stripe_slots_[slot * 2 + c] = {l.stripe, l.cameras[c].scatter};
    tables_[slot * 2 + c] = build_rectify_table(l.cameras[c].model, l.laser, l.lut_step_px);
  }
  fusion_[slot] = l.fusion;
  beams_[slot] = l.xray;
  rays_[slot] = build_ray_table(l.xray, l.fusion);
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
  run(b.frames.data(), b.lines, b.lane_slot.data(), out);
}

void LinePipeline::run(const uint8_t* frames, int lines, const int* lane_slot,
                       LineResults& out) const {
  std::vector<int> frame_slot(size_t(lines) * 2);
  for (int l = 0; l < lines; ++l) {
    if (lane_slot[l] < 0 || lane_slot[l] >= int(lanes_.size()))
      fail("line ", l, " of the batch names lane slot ", lane_slot[l], " which does not exist");
    frame_slot[2 * l] = lane_slot[l] * 2;
    frame_slot[2 * l + 1] = lane_slot[l] * 2 + 1;
  }
  const int count = lines * 2;
  const size_t cols = size_t(count) * width_;
  stripes(frames, count, frame_slot.data(), out.stripes);
  out.x.resize(cols);
  out.z.resize(cols);
  out.xz_valid.resize(cols);
  rectify_rows(out.stripes.row.data(), out.stripes.valid.data(), count, frame_slot.data(),
               out.x.data(), out.z.data(), out.xz_valid.data());
  out.profile.resize(size_t(lines) * grid_n_);
  out.profile_valid.resize(out.profile.size());
  fuse(out.x.data(), out.z.data(), out.xz_valid.data(), lines, lane_slot, out.profile.data(),
       out.profile_valid.data(), &out.fusion);
  out.thickness.resize(size_t(lines) * pixels_);
  out.thickness_valid.resize(out.thickness.size());
  project(out.profile.data(), out.profile_valid.data(), lines, lane_slot, out.thickness.data(),
          out.thickness_valid.data());
}

void LinePipeline::stripes(const uint8_t* frames, int count, const int* frame_slot,
                           StripeOutput& out) const {
  extract_stripes(frames, count, width_, height_, frame_slot, stripe_slots_.data(), out, threads_,
                  vector_blocks_);
}

void LinePipeline::rectify_rows(const float* row, const uint8_t* valid, int count,
                                const int* frame_slot, float* x, float* z,
                                uint8_t* out_valid) const {
  rectify(row, valid, count, width_, frame_slot, tables_.data(), x, z, out_valid);
}

void LinePipeline::fuse(const float* x, const float* z, const uint8_t* valid, int lines,
                        const int* lane_slot, float* profile, uint8_t* profile_valid,
                        FusionStats* stats) const {
  fuse_profiles(x, z, valid, width_, lines, lane_slot, fusion_.data(), grid_n_, profile,
                profile_valid, stats);
}

void LinePipeline::project(const float* profile, const uint8_t* profile_valid, int lines,
                           const int* lane_slot, float* thickness, uint8_t* thickness_valid) const {
  for (int l = 0; l < lines; ++l)
    project_line(rays_[lane_slot[l]], profile + size_t(l) * grid_n_,
                 profile_valid + size_t(l) * grid_n_, thickness + size_t(l) * pixels_,
                 thickness_valid + size_t(l) * pixels_);
}

}  // namespace rangex
