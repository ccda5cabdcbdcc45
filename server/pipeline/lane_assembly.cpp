#include "pipeline/lane_assembly.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/connected_components.h"
#include "pipeline/wall_gaps.h"

namespace rangex {

LaneAssembler::LaneAssembler(const LaneConfig& lane, Sink sink)
    : lane_(lane),
      sink_(std::move(sink)),
      pixels_(lane.xray.pixels),
      open_beam_(double((1 << lane.xray.bits) - 1)) {}

bool LaneAssembler::occupied(const std::vector<float>& t) const {
  for (float v : t)
    if (v > lane_.inspection.floor_mm) return true;
  return false;
}

void LaneAssembler::start_line(int64_t encoder) {
  // Line numbers (belt positions) run from the lane's first line; a count before it, or
  // far beyond it after a restart, starts the numbering again.
  if (first_encoder_ == INT64_MIN || encoder < first_encoder_ ||
      uint64_t(encoder) - uint64_t(first_encoder_) > (uint64_t(1) << 52))
    first_encoder_ = encoder;
}

bool LaneAssembler::advance(int64_t encoder) {
  if (next_encoder_ == INT64_MIN) {
    start_line(encoder);
    next_encoder_ = encoder;
    return true;
  }
  if (encoder < next_encoder_) {
    ++stats_.out_of_order;  // the caller keeps lines in order; nothing to add
    return false;
  }
  const uint64_t gap = uint64_t(encoder) - uint64_t(next_encoder_);
  if (gap == 0) return true;
  const InspectionParams& ip = lane_.inspection;
  if (gap > uint64_t(ip.encoder_horizon_lines)) {
    restart("encoder jumped " + std::to_string(gap) + " counts, beyond the horizon of " +
            std::to_string(ip.encoder_horizon_lines));
    start_line(encoder);
    next_encoder_ = encoder;
    return true;
  }
  // The first delay_lines missing counts pair with camera lines that did come; after them
  // a segment's worth of missing rows closes any open segment. Beyond that nothing changes
  // but the count: skip to a lead-in of missing rows before the next line.
  const uint64_t walk =
      std::min<uint64_t>(gap, uint64_t(lane_.xray.delay_lines) + uint64_t(ip.max_segment_lines));
  for (uint64_t k = 0; k < walk; ++k) add_missing(next_encoder_ + int64_t(k));
  const uint64_t rest = gap - walk;
  const uint64_t lead = std::min<uint64_t>(rest, uint64_t(ip.gap_lines) + 1);
  stats_.lines += int64_t(rest - lead);
  stats_.missing_lines += int64_t(rest - lead);
  for (uint64_t k = lead; k > 0; --k) add_missing(encoder - int64_t(k));
  next_encoder_ = encoder;
  return true;
}

void LaneAssembler::add_missing(int64_t encoder) {
  Row r{encoder, encoder - first_encoder_, {}, {}, {}, true, false};
  // The camera line of this slice may have come before the line went missing: keep what
  // it saw, so that a fillet under the laser is not lost with the X-ray line.
  auto it = thickness_.find(encoder - lane_.xray.delay_lines);
  if (it != thickness_.end()) {
    r.thickness = std::move(it->second);
    r.occupied = occupied(r.thickness);
    thickness_.erase(it);
  }
  ++stats_.lines;
  ++stats_.missing_lines;
  add_row(std::move(r));
}

void LaneAssembler::push_missing(int64_t encoder) {
  if (!advance(encoder)) return;
  add_missing(encoder);
  next_encoder_ = encoder + 1;
}

void LaneAssembler::push(int64_t encoder, const float* t, const uint16_t* xray,
                         const uint16_t* xray_high) {
  if (!advance(encoder)) return;
  thickness_[encoder].assign(t, t + pixels_);
  // Camera lines wait delay_lines for their X-ray line; older ones can no longer pair.
  while (!thickness_.empty() && thickness_.begin()->first < encoder - lane_.xray.delay_lines - 4)
    thickness_.erase(thickness_.begin());
  next_encoder_ = encoder + 1;
  ++stats_.lines;
  Row r{encoder,
        encoder - first_encoder_,
        std::vector<uint16_t>(xray, xray + pixels_),
        xray_high ? std::vector<uint16_t>(xray_high, xray_high + pixels_) : std::vector<uint16_t>(),
        {},
        false,
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
    r.occupied = occupied(r.thickness);
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
    if (occupied(t)) return false;
  return true;
}

void LaneAssembler::close_all(const std::string& reason) {
  // Camera lines still waiting for their X-ray lines become missing rows: the fillet they
  // saw fails safe instead of vanishing.
  bool pending = false;
  for (const auto& [e, t] : thickness_) pending |= occupied(t);
  if (pending)
    while (!thickness_.empty()) add_missing(thickness_.begin()->first + lane_.xray.delay_lines);
  interrupted_ = reason;
  if (open_) close_segment();
  interrupted_.clear();
  thickness_.clear();
  segment_.clear();
  empty_run_ = 0;
  open_ = false;
}

void LaneAssembler::restart(const std::string& reason) {
  close_all(reason);
  next_encoder_ = INT64_MIN;
  last_restart_ = reason;
  ++stats_.restarts;
}

void LaneAssembler::flush() {
  close_all("the lines ended while this fillet was coming in");
}

// Fillet pixels of the open segment, rows x pixels: thicker than the floor on a seen line.
std::vector<uint8_t> LaneAssembler::segment_mask() const {
  const int rows = int(segment_.size()), D = pixels_;
  std::vector<uint8_t> on(size_t(rows) * D, 0);
  // A line is seen when it has a thickness line with some thickness in it: a missing line
  // has none, and a line whose camera frames were lost (black) has no valid sample.
  std::vector<uint8_t> seen(rows, 0);
  for (int r = 0; r < rows; ++r)
    for (float t : segment_[r].thickness)
      if (std::isfinite(t)) {
        seen[r] = 1;
        break;
      }
  for (int r = 0; r < rows; ++r) {
    if (!seen[r]) continue;
    const Row& row = segment_[r];
    for (int i = 0; i < D; ++i)
      on[size_t(r) * D + i] = row.thickness[i] > lane_.inspection.floor_mm;
  }
  // A line with no thickness must not cut a fillet in two: it takes the union of its
  // neighbours, so the fillet stays one region; a missing line goes into its fail-safe
  // check, a blind one has its thickness closed from its neighbours (close_wall_gaps).
  for (int r = 0; r < rows; ++r) {
    if (seen[r]) continue;
    int up = r - 1, dn = r + 1;
    while (up >= 0 && !seen[up]) --up;
    while (dn < rows && !seen[dn]) ++dn;
    for (int i = 0; i < D; ++i)
      on[size_t(r) * D + i] =
          (up >= 0 && on[size_t(up) * D + i]) || (dn < rows && on[size_t(dn) * D + i]);
  }
  return on;
}

// One fillet's image: its component's box with a 2-pixel margin, with the lane's geometry.
FilletImage LaneAssembler::cut_fillet(const Component& c, const std::vector<int>& labels,
                                      int missing, bool interrupted) {
  const int rows = int(segment_.size()), D = pixels_;
  const InspectionParams& ip = lane_.inspection;
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
  const FanBeam& fb = lane_.xray;
  if (fb.measured_delay_lines != 0) f.shift_lines = fb.measured_delay_lines - fb.delay_lines;
  f.tan_alpha = std::tan(fb.plane_alpha_deg * M_PI / 180);
  f.tan_beta = std::tan(fb.plane_beta_deg * M_PI / 180);
  f.detector_sigma_px = fb.detector_sigma_px;
  f.focal_spot_sigma_mm = fb.focal_spot_sigma_mm;
  f.has_dual_energy = fb.energies == 2 && fb.has_dual_energy;
  if (f.has_dual_energy) f.dual_energy = fb.dual_energy;
  f.touches_lane_edge = c.col0 == 0 || c.col1 == D - 1;
  f.missing_lines = missing;
  if (interrupted) f.interrupted = interrupted_;
  f.xray.assign(f.size(), 0);
  const bool dual = std::any_of(segment_.begin() + r0, segment_.begin() + r1 + 1,
                                [](const Row& row) { return !row.xray_high.empty(); });
  if (dual) f.xray_high.assign(f.size(), 0);
  f.thickness.assign(f.size(), std::numeric_limits<float>::quiet_NaN());
  f.mask.assign(f.size(), 0);
  std::vector<uint8_t> present(f.size(), 0);
  for (int r = r0; r <= r1; ++r) {
    const Row& row = segment_[r];
    if (row.missing) continue;
    for (int i = c0; i <= c1; ++i) {
      const size_t o = size_t(r - r0) * f.cols + (i - c0);
      f.xray[o] = row.xray[i];
      if (dual && !row.xray_high.empty()) f.xray_high[o] = row.xray_high[i];
      f.thickness[o] = row.thickness[i];
      f.mask[o] = labels[size_t(r) * D + i] == c.label;
      present[o] = 1;
    }
  }
  f.wall_gap_px = close_wall_gaps(f, ip.max_wall_gap_px, ip.floor_mm);
  // Meat by the X-ray with no thickness: the laser lost it.
  const float meat_level = float(0.9 * open_beam_);
  for (size_t o = 0; o < f.size(); ++o)
    f.invalid_thickness_px +=
        present[o] && !std::isfinite(f.thickness[o]) && f.xray[o] < meat_level;
  return f;
}

void LaneAssembler::close_segment() {
  const int rows = int(segment_.size()), D = pixels_;
  const InspectionParams& ip = lane_.inspection;
  const std::vector<uint8_t> on = segment_mask();
  std::vector<int> labels;
  const auto comps = label_components(on.data(), rows, D, labels);
  const double px_area = lane_.xray.pitch_mm * lane_.encoder_step_mm;
  for (const Component& c : comps) {
    int missing = 0;
    for (int r = std::max(0, c.row0 - 1); r <= std::min(rows - 1, c.row1 + 1); ++r)
      missing += segment_[r].missing;
    // A fillet still coming in when the lane restarted did not end here.
    const bool interrupted = !interrupted_.empty() && c.row1 >= rows - 1 - ip.gap_lines;
    // Part of a fillet (cut by missing lines or a restart) can look small: it is reported
    // not inspected, never dismissed as debris.
    if (c.pixels * px_area < ip.min_fillet_area_mm2 && missing == 0 && !interrupted) {
      ++stats_.debris;
      continue;
    }
    ++stats_.fillets;
    sink_(cut_fillet(c, labels, missing, interrupted));
  }
  segment_.clear();
  empty_run_ = 0;
  open_ = false;
}

}  // namespace rangex
