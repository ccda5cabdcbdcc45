// X-ray fan-beam geometry from a pin phantom (Laser Range Imaging §6.3.2.3-4, Figure 27, Table 9):
// the source position, the detector's offset, pitch, height and tilt, fitted by Levenberg-
// Marquardt (Ceres) to where each pin's shadow falls on the detector.
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "calib/solve_report.h"
#include "core/fan_beam.h"

namespace rangex {

struct PinObservation {
  std::string name;           // e.g. "row 3 pin 7 (x -20 mm, z 40 mm)", for messages
  double x_mm = 0, z_mm = 0;  // pin centre in the fan's plane (lane coordinates)
  double pixel = 0;           // shadow centre on the detector, pixel 0's centre = 0
};

struct FanBeamSolveOptions {
  FanBeam start;  // nominal geometry (data sheet, plant.yaml): the start and held values
  // Scale gauge: pitch and the source-detector distance cannot both be free. Fit the pitch
  // with detector_z held (the mounting is measured), or the detector's height with the
  // pitch held (the data sheet's pitch).
  bool fit_pitch = true;
  bool fit_tilt = true;
  double huber_px = 1.0;  // 0: plain least squares
  // One lateral offset per row of pins (pins at one height), for phantoms whose rows are
  // placed by hand or scanned in separate passes (Table 9's rows are offset by up to 0.3
  // mm). The offsets' mean and their trend with height are held at zero: those are the
  // detector offset and the source's x, which stay with the geometry.
  bool row_offsets = false;
  std::function<void(const std::string&)> progress;
};

struct FanBeamFit {
  FanBeam beam;
  std::vector<Estimate> estimates;  // source_x, source_z, first_pixel_x, pitch|detector_z, tilt
  std::vector<double> residual_px;  // observed - model, per observation
  double rms_px = 0, worst_px = 0, rms_mm = 0, worst_mm = 0;
  std::string worst_pin;
  std::vector<std::pair<double, double>> row_offsets_mm;  // (height, offset) when fitted
  bool converged = false;
  SolveReport report(const std::string& subject) const;
};

// Detector coordinate (pixels, pixel 0's centre = 0) where the ray from the source through
// (x, z) meets the detector line; NaN when it runs parallel to it.
double fan_beam_pixel(const FanBeam& fb, double x_mm, double z_mm);

// Throws Error for fewer than 6 pins, NaN or absurd values (a pin below the detector or
// above the source), or pins that leave the geometry undetermined (all at one height).
FanBeamFit fit_fan_beam(const std::vector<PinObservation>& pins, const FanBeamSolveOptions& opt);

}  // namespace rangex
