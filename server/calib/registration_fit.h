// Laser-to-X-ray registration (seed §6.3.2.5, eqs. 41-44, §6.4.3): blocks scanned by both
// planes; the line at which each block's leading and trailing walls cross the laser plane
// (from the laser heights) and the X-ray plane (from the attenuation) differ by the delay
// between the planes, which changes across the belt with the angle alpha (about the
// vertical) and with height with the angle beta (about the lateral axis):
//   delay(x, z) = d0 + (x tan(alpha) + z tan(beta)) / encoder_step.
// Fitted by least squares over every lateral position of every wall.
#pragma once
#include <cstdint>
#include <vector>

#include "calib/solve_report.h"
#include "core/calibration_objects.h"
#include "core/camera_model.h"
#include "core/fan_beam.h"

namespace rangex {

// Laser heights per line on a lateral grid (NaN where no camera saw the surface).
struct LaserProfiles {
  double x0_mm = -100, pitch_mm = 0.5;
  int n = 401;
  int64_t lines = 0;
  std::vector<float> h;  // lines x n
};

struct RegistrationFit {
  double delay_lines = 0, delay_std = 0;  // at x = 0, z = 0
  double alpha_deg = 0, alpha_std = 0;
  double beta_deg = 0, beta_std = 0;
  double rms_lines = 0;
  double corner_mean_mm = 0, corner_worst_mm = 0;  // block corners, laser vs X-ray
  int blocks = 0, observations = 0;
  SolveReport report(const std::string& subject) const;
};

// Both cameras' stripe rows (lines x width, NaN where none) on the plane y = 0, binned
// onto the lateral grid (the mean of what falls in a bin).
LaserProfiles laser_profiles(const float* rows0, const float* rows1, int64_t lines, int width,
                             const CameraModel& cam0, const CameraModel& cam1);

// Throws Error naming the block when a block is not seen by both planes or the blocks
// found do not match the set's count.
RegistrationFit fit_registration(const LaserProfiles& laser, const uint16_t* xray, int64_t lines,
                                 const FanBeam& beam, double encoder_step_mm,
                                 const BlockSet& blocks);

}  // namespace rangex
