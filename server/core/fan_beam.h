// X-ray fan-beam geometry of one lane: a point source above the belt and a line detector
// below it, both in the X-ray plane, which lies delay_lines encoder steps downstream of the
// laser plane and parallel to it.
#pragma once
#include <cmath>
#include <string>

#include "core/sandwich_detector.h"
#include "shared/dual_energy.h"

namespace rangex {

struct FanBeam {
  int pixels = 512;
  double pitch_mm = 0.4;
  double first_pixel_x_mm = -102.2;  // centre of detector pixel 0
  double detector_z_mm = -15.0;      // detector surface below the belt
  double source_x_mm = 0.0;
  double source_z_mm = 700.0;  // focal spot above the belt
  double tilt_deg = 0;         // detector line rotated in the x-z plane (pixel i rises)
  int delay_lines = 50;        // X-ray plane offset from the laser plane, in encoder steps
  int bits = 12;
  // Measured optics (calib xray): the detector's line-spread function and the focal spot,
  // for a pseudo-X-ray that matches the real one at edges.
  double detector_sigma_px = 0;
  double focal_spot_sigma_mm = 0;
  // The registration's measurement (calib registration, eqs. 41-44): the delay at x = 0,
  // z = 0 to a fraction of a line, and the X-ray plane's angles against the laser's about
  // the vertical (alpha) and the lateral axis (beta). The line path registers whole lines
  // (delay_lines). 0: not measured.
  double measured_delay_lines = 0;
  double plane_alpha_deg = 0, plane_beta_deg = 0;
  // Dual energy (docs/dual-energy.md): 2 for a sandwich detector's low and high lines, read
  // together (LineScan.xray is the low line, xray_high the high one); its layers and tube.
  int energies = 1;
  SandwichDetector sandwich;
  // The lane's dual-energy calibration (rangexctl calib dual-energy: the step wedge's fit);
  // without one a dual-energy lane inspects its low line as a lane of one energy does.
  bool has_dual_energy = false;
  kernel::DualEnergyK dual_energy{};
  std::string dual_energy_fitted_on;  // the wedge scan it was fitted on

  // Pixel i's centre at (first_pixel_x_mm + pitch_x() * i, detector_z_mm + pitch_z() * i).
  double pitch_x() const { return pitch_mm * std::cos(tilt_deg * M_PI / 180); }
  double pitch_z() const { return pitch_mm * std::sin(tilt_deg * M_PI / 180); }
  double pixel_x(int i) const { return first_pixel_x_mm + pitch_x() * i; }
  double pixel_z(int i) const { return detector_z_mm + pitch_z() * i; }
  // Path length along pixel i's ray through a horizontal slab of 1 mm: 1 / cos(theta), theta
  // the ray's angle from the vertical.
  double slab_path_factor(int i) const {
    const double dz = source_z_mm - pixel_z(i);
    return std::hypot(source_x_mm - pixel_x(i), dz) / dz;
  }
};

}  // namespace rangex
