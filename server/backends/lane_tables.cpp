#include "backends/lane_tables.h"

#include <cmath>

#include "core/error.h"
#include "pipeline/stripe_column.h"

namespace rangex {

void KernelTables::set_lanes(const std::vector<LaneConfig>& lanes) {
  if (lanes.empty()) fail("a backend needs at least one lane");
  lanes_ = lanes;
  const LaneConfig& f = lanes.front();
  width = f.frame_width;
  height = f.frame_height;
  grid_n = f.fusion.grid_samples;
  pixels = f.xray.pixels;
  tables_.clear();
  for (const LaneConfig& l : lanes) {
    if (l.frame_width != width || l.frame_height != height || l.fusion.grid_samples != grid_n ||
        l.xray.pixels != pixels)
      fail("lane ", l.id, " differs in frame size, fusion grid or detector pixels from lane ", f.id,
           "; such lanes run in separate pipelines");
    for (int c = 0; c < 2; ++c)
      tables_.push_back(build_rectify_table(l.cameras[c].model, l.laser, l.lut_step_px));
  }
  ln.assign(std::begin(stripe::ln_table().v), std::end(stripe::ln_table().v));
  pack();
}

void KernelTables::update_lane(int slot, const LaneConfig& l) {
  if (slot < 0 || slot >= int(lanes_.size())) fail("no lane slot ", slot);
  if (l.frame_width != width || l.frame_height != height || l.fusion.grid_samples != grid_n ||
      l.xray.pixels != pixels)
    fail("lane ", l.id, ": a new configuration may not change sensor or grid sizes");
  lanes_[slot] = l;
  for (int c = 0; c < 2; ++c)
    tables_[size_t(slot) * 2 + c] = build_rectify_table(l.cameras[c].model, l.laser, l.lut_step_px);
  pack();
}

void KernelTables::pack() {
  stripe.clear();
  rect.clear();
  nodes.clear();
  geom.clear();
  for (size_t s = 0; s < lanes_.size(); ++s) {
    const LaneConfig& l = lanes_[s];
    for (int c = 0; c < 2; ++c) {
      const ScatterConstants& sc = l.cameras[c].scatter;
      stripe.push_back({int(l.stripe.method), l.stripe.min_peak, float(l.stripe.threshold_rel),
                        l.stripe.max_width, float(sc.k1), float(sc.k2), float(sc.k2_offset), 0});
      const RectifyTable& t = tables_[s * 2 + c];
      rect.push_back({t.step, t.nu, t.nv, int(nodes.size())});
      nodes.insert(nodes.end(), t.x.begin(), t.x.end());
      nodes.insert(nodes.end(), t.z.begin(), t.z.end());
    }
    const FusionParams& fp = l.fusion;
    const FanBeam& fb = l.xray;
    kernel::LaneGeomK g{};
    g.grid_x0_mm = fp.grid_x0_mm;
    g.grid_pitch_mm = fp.grid_pitch_mm;
    g.agree_tol_mm = fp.agree_tol_mm;
    g.max_column_step_mm = fp.max_column_step_mm;
    g.first_pixel_x_mm = fb.first_pixel_x_mm;
    g.pitch_mm = fb.pitch_x();
    g.pitch_z_mm = fb.pitch_z();
    g.detector_z_mm = fb.detector_z_mm;
    g.source_x_mm = fb.source_x_mm;
    g.source_z_mm = fb.source_z_mm;
    g.grid_n = fp.grid_samples;
    g.pixels = fb.pixels;
    g.max_gap = int(std::floor(fp.max_gap_mm / fp.grid_pitch_mm + 1e-9));  // as fuse_profiles
    geom.push_back(g);
  }
}

}  // namespace rangex
