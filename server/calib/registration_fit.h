// Laser-to-X-ray registration (Laser Range Imaging §6.3.2.5, eqs. 41-44, §6.4.3) from blocks
// scanned by both planes.
// - Along the belt: the line at which each block's leading and trailing walls cross the
//   laser plane (from the laser heights) and the X-ray plane (from the attenuation) differ
//   by the delay between the planes, which changes across the belt with the angle alpha
//   (about the vertical) and with height with the angle beta (about the lateral axis):
//     delay(x, z) = d0 + (x tan(alpha) + z tan(beta)) / encoder_step.
// - Across the belt: the staircase fixes the laser's lateral origin where it stood, the pin
//   phantom the X-ray's where it stood; both were placed by hand. Where each camera sees a
//   block's top end and where the X-ray sees its side wall give the offset between the
//   frames, which moves both cameras into the X-ray's. The stripe loses columns where a
//   top ends (its window sees the top and the floor through the optics' blur): that
//   erosion, in columns, is fitted per camera beside the offset.
// The result is judged as §6.4.3 does: block corners located in the laser image, carried
// into the X-ray's lines by the registration, against the same corners in the X-ray.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "calib/block_walls.h"
#include "calib/solve_report.h"
#include "core/calibration_objects.h"
#include "core/camera_model.h"
#include "core/fan_beam.h"

namespace rangex {

struct RegistrationScan {
  const float* rows[2] = {nullptr, nullptr};  // each camera's stripe rows, lines x width
  int width = 0;
  const uint16_t* xray = nullptr;  // lines x pixels
  int64_t lines = 0;
};

struct RegistrationOptions {
  bool fit_offset = true;    // false: measure through the given cameras (calib validate)
  bool solve_planes = true;  // false: use delay/alpha/beta below (calib validate)
  double delay_lines = 0, alpha_deg = 0, beta_deg = 0;
};

struct RegistrationFit {
  double delay_lines = 0, delay_std = 0;  // at x = 0, z = 0
  double alpha_deg = 0, alpha_std = 0;
  double beta_deg = 0, beta_std = 0;
  double rms_lines = 0;
  double offset_mm = 0, offset_std = 0;  // laser frame vs X-ray frame, across the belt
  CameraModel cameras[2];                // moved by the offset (or as given)
  double erosion_px[2] = {0, 0}, erosion_std[2] = {0, 0};
  double side_rms_px = 0;  // top ends against the X-ray's side walls, after the fit
  int top_ends = 0;
  // Block corners: laser (cameras + registration) against X-ray.
  double corner_mean_mm = 0, corner_worst_mm = 0;
  double along_mean_mm = 0, across_mean_mm = 0;  // mean absolute components
  int corners = 0, blocks = 0, observations = 0;
  SolveReport report(const std::string& subject) const;
};

// Throws Error naming the block when a block is not seen by both planes, the blocks found
// do not match the set's count, or a wall cannot be located.
RegistrationFit fit_registration(const RegistrationScan& scan, const CameraModel& cam0,
                                 const CameraModel& cam1, const FanBeam& beam,
                                 double encoder_step_mm, const BlockSet& blocks,
                                 const RegistrationOptions& options = {});

}  // namespace rangex
