#include "pipeline/lane_assembly.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/connected_components.h"

namespace rangex {

LaneAssembler::LaneAssembler(const LaneConfig& lane, Sink sink)
    : lane_(lane),
      sink_(std::move(sink)),
      pixels_(lane.xray.pixels),
      open_beam_(double((1 << lane.xray.bits) - 1)) {}

void LaneAssembler::push_thickness(int64_t encoder, const float* t) {
  if (first_encoder_ == INT64_MIN) first_encoder_ = encoder;
  thickness_[encoder].assign(t, t + pixels_);
  // Camera lines wait delay_lines for their X-ray line; older ones can no longer pair.
  while (!thickness_.empty() && thickness_.begin()->first < encoder - lane_.xray.delay_lines - 4)
    thickness_.erase(thickness_.begin());
}

void LaneAssembler::push_missing(int64_t encoder) {
  if (first_encoder_ == INT64_MIN) first_encoder_ = encoder;
  if (next_encoder_ != INT64_MIN && encoder < next_encoder_) return;  // already accounted
  Row r{encoder, encoder - first_encoder_, {}, {}, true, false};
  next_encoder_ = encoder + 1;
  ++stats_.lines;
  ++stats_.missing_lines;
  add_row(std::move(r));
}

void LaneAssembler::push_xray(int64_t encoder, const uint16_t* xray) {
  if (first_encoder_ == INT64_MIN) first_encoder_ = encoder;
  if (next_encoder_ != INT64_MIN && encoder < next_encoder_) return;  // the caller checks order
  // Lines that never came are missing lines.
  if (next_encoder_ != INT64_MIN)
    for (int64_t e = next_encoder_; e < encoder; ++e) push_missing(e);
  next_encoder_ = encoder + 1;
  ++stats_.lines;
  Row r{encoder, encoder - first_encoder_, std::vector<uint16_t>(xray, xray + pixels_), {}, false,
        false};
  auto it = thickness_.find(encoder - lane_.xray.delay_lines);
  if (it == thickness_.end()) {
    // No camera line for this slice: no thickness, so the line cannot be inspected.
    r.missing = true;
    ++stats_.missing_lines;
  } else {
    r.thickness = std::move(it->second);
    thickness_.erase(it);
    // Track the bare-belt X-ray level (used to find meat that has no thickness).
    std::vector<uint16_t> belt;
    for (int i = 0; i < pixels_; ++i)
      if (std::isfinite(r.thickness[i]) && r.thickness[i] < 0.3f) belt.push_back(r.xray[i]);
    if (belt.size() > size_t(pixels_ / 8)) {
      std::nth_element(belt.begin(), belt.begin() + long(belt.size() / 2), belt.end());
      open_beam_ = 0.9 * open_beam_ + 0.1 * belt[belt.size() / 2];
    }
    for (int i = 0; i < pixels_ && !r.occupied; ++i)
      r.occupied = r.thickness[i] > lane_.inspection.floor_mm;
  }
  add_row(std::move(r));
}

void LaneAssembler::add_row(Row&& row) {
  const bool occupied = row.occupied, content = row.occupied || row.missing;
  segment_.push_back(std::move(row));
  if (!open_) {
    // Keep a short lead-in so that a missing line just before a fillet is seen with it.
    while (int(segment_.size()) > lane_.inspection.gap_lines + 1) segment_.pop_front();
    open_ = occupied;
    empty_run_ = 0;
    return;
  }
  empty_run_ = content ? 0 : empty_run_ + 1;
  if (empty_run_ >= lane_.inspection.gap_lines ||
      int(segment_.size()) >= lane_.inspection.max_segment_lines)
    close_segment();
}

bool LaneAssembler::quiet() const {
  if (open_) return false;
  for (const auto& [e, t] : thickness_)
    for (float v : t)
      if (v > lane_.inspection.floor_mm) return false;
  return true;
}

void LaneAssembler::flush() {
  if (open_) close_segment();
  segment_.clear();
  empty_run_ = 0;
}

void LaneAssembler::close_segment() {
  const int rows = int(segment_.size()), D = pixels_;
  const InspectionParams& ip = lane_.inspection;
  std::vector<uint8_t> on(size_t(rows) * D, 0);
  for (int r = 0; r < rows; ++r) {
    const Row& row = segment_[r];
    if (row.missing) continue;
    for (int i = 0; i < D; ++i) on[size_t(r) * D + i] = row.thickness[i] > ip.floor_mm;
  }
  // A missing line must not cut a fillet in two: it takes the union of its neighbours, so
  // the fillet stays one region and carries the missing line into its fail-safe check.
  for (int r = 0; r < rows; ++r) {
    if (!segment_[r].missing) continue;
    int up = r - 1, dn = r + 1;
    while (up >= 0 && segment_[up].missing) --up;
    while (dn < rows && segment_[dn].missing) ++dn;
    for (int i = 0; i < D; ++i)
      on[size_t(r) * D + i] =
          (up >= 0 && on[size_t(up) * D + i]) || (dn < rows && on[size_t(dn) * D + i]);
  }
  std::vector<int> labels;
  const auto comps = label_components(on.data(), rows, D, labels);
  const double px_area = lane_.xray.pitch_mm * lane_.encoder_step_mm;
  const float meat_level = float(0.9 * open_beam_);
  for (const Component& c : comps) {
    if (c.pixels * px_area < ip.min_fillet_area_mm2) {
      ++stats_.debris;
      continue;
    }
    FilletImage f;
    f.lane = lane_.id;
    f.id = next_id_++;
    const int r0 = std::max(0, c.row0 - 2), r1 = std::min(rows - 1, c.row1 + 2);
    const int c0 = std::max(0, c.col0 - 2), c1 = std::min(D - 1, c.col1 + 2);
    f.rows = r1 - r0 + 1;
    f.cols = c1 - c0 + 1;
    f.first_line = segment_[r0].line;
    f.first_encoder = segment_[r0].encoder;
    f.first_col = c0;
    f.pitch_mm = lane_.xray.pitch_mm;
    f.step_mm = lane_.encoder_step_mm;
    f.x0_mm = lane_.xray.pixel_x(c0);
    f.y0_mm = double(f.first_line - lane_.xray.delay_lines) * lane_.encoder_step_mm;
    f.bits = lane_.xray.bits;
    f.source_x_mm = lane_.xray.source_x_mm;
    f.source_z_mm = lane_.xray.source_z_mm;
    f.detector_z_mm = lane_.xray.detector_z_mm;
    f.touches_lane_edge = c.col0 == 0 || c.col1 == D - 1;
    f.xray.assign(f.size(), 0);
    f.thickness.assign(f.size(), std::numeric_limits<float>::quiet_NaN());
    f.mask.assign(f.size(), 0);
    for (int r = std::max(0, c.row0 - 1); r <= std::min(rows - 1, c.row1 + 1); ++r)
      f.missing_lines += segment_[r].missing;
    for (int r = r0; r <= r1; ++r) {
      const Row& row = segment_[r];
      if (row.missing) continue;
      for (int i = c0; i <= c1; ++i) {
        const size_t o = size_t(r - r0) * f.cols + (i - c0);
        f.xray[o] = row.xray[i];
        f.thickness[o] = row.thickness[i];
        f.mask[o] = labels[size_t(r) * D + i] == c.label;
        // Meat by the X-ray with no thickness: the laser lost it.
        if (!std::isfinite(row.thickness[i]) && row.xray[i] < meat_level) ++f.invalid_thickness_px;
      }
    }
    ++stats_.fillets;
    sink_(std::move(f));
  }
  segment_.clear();
  empty_run_ = 0;
  open_ = false;
}

}  // namespace rangex
