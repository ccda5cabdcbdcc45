// One fillet cut out of a lane's stacked images: X-ray counts and registered X-ray path
// thickness over its bounding box, the fillet's mask, and what went wrong on the way.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "shared/dual_energy.h"

namespace rangex {

struct FilletImage {
  int lane = 0;
  int64_t id = 0;          // per lane, in order of arrival
  int64_t first_line = 0;  // lane X-ray line index of row 0
  int64_t first_encoder = 0;
  int first_col = 0;  // detector pixel of column 0
  int rows = 0, cols = 0;
  double pitch_mm = 0.4;  // across the belt (detector pixel)
  double step_mm = 0.4;   // along the belt (encoder step)
  double x0_mm = 0;       // x of column 0's centre
  double y0_mm = 0;       // belt position (object coordinate) of row 0
  // Fan-beam geometry, to place what the detector sees back onto the belt.
  double source_x_mm = 0, source_z_mm = 700, detector_z_mm = -15;
  // What the detector does that the thickness does not show (the lane's calibration):
  // the registration beyond whole lines (delay(x, z) - delay_lines = shift_lines +
  // (x tan_alpha + z tan_beta) / step_mm) and the blur across the detector.
  double shift_lines = 0, tan_alpha = 0, tan_beta = 0;
  double detector_sigma_px = 0, focal_spot_sigma_mm = 0;
  bool matches_detector() const {
    return shift_lines != 0 || tan_alpha != 0 || tan_beta != 0 || detector_sigma_px > 0 ||
           focal_spot_sigma_mm > 0;
  }
  std::vector<uint16_t> xray;       // rows * cols, DN (a dual-energy lane's low-energy line)
  std::vector<uint16_t> xray_high;  // a dual-energy lane's high-energy line; empty otherwise
  // The lane's dual-energy calibration, when it has one (core/fan_beam.h).
  bool has_dual_energy = false;
  kernel::DualEnergyK dual_energy{};
  std::vector<float> thickness;  // rows * cols, mm of X-ray path; NaN where not measured
  std::vector<uint8_t> mask;     // rows * cols, 1 on the fillet
  // rows * cols, or empty: each pixel closed from a gap's ends (a wall's hidden rim, a lost
  // camera frame's row) holds how far those two differ (mm), 0 elsewhere. The thickness there
  // lies somewhere between them, wherever the step between them stood (pipeline/wall_gaps.h).
  std::vector<float> closure_step_mm;
  int bits = 12;
  // Fail-safe inputs, filled by the assembly.
  int missing_lines = 0;         // lines of the fillet that never arrived or were dropped
  int invalid_thickness_px = 0;  // meat pixels (by X-ray) without a thickness
  int wall_gap_px = 0;           // pixels closed as a steep wall's hidden rim
  bool touches_lane_edge = false;
  bool calibration_mismatch = false;
  std::string interrupted;  // why the lane restarted while this fillet was coming in

  size_t size() const { return size_t(rows) * cols; }
  int mask_pixels() const {
    int n = 0;
    for (uint8_t m : mask) n += m;
    return n;
  }
};

}  // namespace rangex
