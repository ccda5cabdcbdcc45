// A camera's pose relative to the laser plane and the belt from a scan of the CNC staircase
// (Laser Range Imaging §6.4.2, Table 5): the stripe on every step top lies at a known height, and
// the steps' walls at known x; Levenberg-Marquardt (Ceres) moves the camera until the stripe's rays
// meet the plane y = 0 at those heights and walls. The intrinsics stay as calibrated. The result is
// reported per step as in Table 5: mean, std and error of the measured height.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "calib/solve_report.h"
#include "core/calibration_objects.h"
#include "core/camera_model.h"

namespace rangex {

struct StepStat {
  double height_mm = 0;  // the drawing's
  double mean_mm = 0, std_mm = 0, error_mm = 0;
  int64_t samples = 0;
};

struct StaircaseFit {
  CameraModel camera;               // the start's intrinsics with the solved pose
  std::vector<Estimate> estimates;  // centre x/y/z (mm), rotation about x/y/z (deg) vs start
  std::vector<StepStat> steps;      // after the fit, every line's columns (Table 5)
  double height_rms_mm = 0, height_worst_mm = 0;  // column means about the drawing
  double height_rms_px = 0;                       // the same along the image rows
  double edge_rms_px = 0;
  double edge_erosion_px = 0;  // columns the stripe loses at a wall, per side
  double worst_step_error_mm = 0;
  int plateaus = 0;
  bool converged = false;
  SolveReport report(const std::string& subject) const;
};

// rows: lines x width stripe rows of one camera (NaN where none), from a scan of `stairs`.
// Throws Error naming the camera and step when steps are missing or the scan holds no
// block.
// solve = false: only measure the steps through `start` (calib validate).
StaircaseFit fit_staircase(const float* rows, int64_t lines, int width, const CameraModel& start,
                           const Staircase& stairs, const std::string& camera, bool solve = true);

// Heights of every stripe point on the plane y = 0 through `cam` (NaN where none).
double plane_height(const CameraModel& cam, double u, double v, double* x_mm = nullptr);

}  // namespace rangex
