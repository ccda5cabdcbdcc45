// A simulated rig: a lane as a real plant's would stand, for calibration scans and plant runs.
#pragma once
#include "core/plant_config.h"

namespace rangex::sim {

// A rig that differs from `nominal` as a real plant's would (cameras moved on their mounts,
// the fan beam shifted and tilted, the X-ray plane at a fractional delay and small angles),
// drawn from `seed` (and the lane's id); the X-ray optics it has. The plant simulator
// renders its lane (parallel planes at the whole-line delay); calibration scans also render
// the planes' small angles.
struct SimulatedRig {
  LaneConfig lane;
  double xray_plane_y_mm, alpha_rad, beta_rad;
  double detector_sigma_px = 0.6, focal_spot_sigma_mm = 0.8;
  // Where the staircase really stands across the belt against its drawing (it leans on a
  // fence placed by hand; the pin phantom defines the lane's frame).
  double staircase_offset_mm = 0;
};
SimulatedRig perturbed_rig(const LaneConfig& nominal, unsigned long seed);

}  // namespace rangex::sim
