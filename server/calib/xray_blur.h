// The X-ray's blur from the pin shadows' widths: a pin at height z is blurred by the
// detector's line-spread function (sigma_d px, the same everywhere) and by the focal spot
// (sigma_f mm at the source, magnified onto the detector by (z - z_det) / (z_src - z)),
// sigma(z)^2 = sigma_d^2 + (sigma_f (z - z_det) / (z_src - z) / pitch)^2, fitted by weighted
// least squares over all pins.
#pragma once
#include <vector>

#include "calib/pin_shadows.h"
#include "calib/solve_report.h"

namespace rangex {

struct XrayBlurFit {
  double detector_sigma_px = 0, detector_std = 0;
  double focal_spot_sigma_mm = 0, focal_spot_std = 0;
  double rms_px = 0;  // of the pins' sigma about the model
  SolveReport report(const std::string& subject) const;
};

// Throws Error with fewer than 4 pins or pins at a single height.
XrayBlurFit fit_xray_blur(const std::vector<PinShadow>& pins, const FanBeam& geometry);

}  // namespace rangex
