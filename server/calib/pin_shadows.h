// Pin shadows in an X-ray scan of the pin phantom: which lines carry each row of pins,
// and for every pin its shadow's centre on the detector and its width, from a fit of the
// pin's transmission profile (a circle's chord through the fan) blurred by a Gaussian.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "calib/fan_beam_fit.h"
#include "core/calibration_objects.h"
#include "core/fan_beam.h"

namespace rangex {

struct PinShadow {
  PinObservation at;     // the pin (from the drawing) and where its shadow falls
  double sigma_px = 0;   // Gaussian blur of the shadow's edges
  double sigma_std = 0;  // its standard error
};

// xray: lines x pixels. nominal: the geometry to expect (plant.yaml), used to order the
// shadows and to refuse pins that fall outside the detector. Throws Error naming the row
// or pin when a row is missing, a pin is out of view or its shadow is not found.
std::vector<PinShadow> measure_pin_shadows(const uint16_t* xray, int64_t lines, int pixels,
                                           const PinPhantom& phantom, const FanBeam& nominal);

}  // namespace rangex
