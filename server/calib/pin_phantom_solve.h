// The fan beam's geometry and blur from a pin phantom: pins measured in a scan
// (pin_phantom.yaml beside it) or listed in a CSV (x_mm,z_mm,pixel), the fan beam fitted,
// the blur fitted from the pins' shadows when there is a scan, and the pins' residuals
// along the detector drawn as a plot.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "calib/fan_beam_fit.h"
#include "calib/pin_shadows.h"
#include "calib/xray_blur.h"
#include "core/recording.h"

namespace rangex {

// x_mm,z_mm,pixel per line; '#' comments and a header line starting with 'x' are skipped.
std::vector<PinObservation> read_pin_csv(const std::string& path);
// The pins' shadows in a scan's X-ray lines, measured from `start`'s geometry.
std::vector<PinShadow> measure_scan_pins(const RecordingReader& rec, const FanBeam& start);

struct PinPhantomSolve {
  FanBeamFit fit;
  std::optional<XrayBlurFit> blur;  // with shadows
  FanBeam beam;                     // the fitted geometry with the fitted blur
};

// `shadows` may be empty (pins from a CSV: no blur). With `residuals_png`, the plot.
PinPhantomSolve solve_pin_phantom(const std::vector<PinObservation>& pins,
                                  const std::vector<PinShadow>& shadows,
                                  const FanBeamSolveOptions& opt, int detector_pixels,
                                  const std::string& residuals_png);

}  // namespace rangex
