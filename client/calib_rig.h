// The integrator's calibration files: a lane's calibration YAML (the sections of
// plant.yaml) read over the plant's lane, written back after each solve, and the solvers'
// reports kept beside it in <file>.reports/ (one JSON per solver and subject).
#pragma once
#include <string>
#include <vector>

#include "calib/solve_report.h"
#include "core/plant_config.h"

namespace rangex::cli {

// --calibration FILE over the plant's lane, or the plant's lane itself.
LaneConfig load_lane_calibration(const PlantConfig& plant, int lane, const std::string& file);
// --calibration FILE (every lane) or L:FILE,L:FILE applied over the plant's lanes.
void apply_calibration_option(PlantConfig& plant, const std::string& value);
void save_lane_calibration(const LaneConfig& lane, const std::string& file,
                           const SolveReport& report);
// Every report saved beside `file`, as one {"reports": [...]} document ("" when none).
std::string lane_reports_json(const std::string& file);

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

}  // namespace rangex::cli
