// X-ray lines of calibration objects with the optics a real detector has: a focal spot of
// finite size (penumbra that grows with the object's height), a detector line-spread
// function, and an X-ray plane that may stand at small angles to the laser plane (seed
// eq. 41). Paths through boxes and pins are exact (3D ray against slabs and cylinders).
#pragma once
#include <cstdint>
#include <limits>

#include "core/lane_config.h"
#include "sim/calib_objects.h"
#include "sim/rng.h"
#include "sim/xray_renderer.h"

namespace rangex::sim {

struct XrayOptics {
  double focal_spot_sigma_mm = 0.0;  // Gaussian spread of the source across the fan
  double detector_sigma_px = 0.0;    // Gaussian line-spread function of the detector
  // The X-ray plane y = plane_y_mm + x tan(alpha) + z tan(beta) in lane coordinates; NaN
  // plane_y_mm: laser offset + delay_lines * encoder step (the nominal parallel plane).
  double plane_y_mm = std::numeric_limits<double>::quiet_NaN();
  double alpha_rad = 0, beta_rad = 0;
};

class CalibXrayRenderer {
 public:
  CalibXrayRenderer(const LaneConfig& lane, XrayOptics optics, XrayRenderParams p = {});
  void render(const CalibScene& scene, double belt_offset_mm, Rng& rng, uint16_t* line) const;
  double plane_y(double x, double z) const;

 private:
  FanBeam fb_;
  XrayOptics o_;
  XrayRenderParams p_;
  double tan_alpha_, tan_beta_;  // the plane's tilts, taken once (plane_y runs for every ray)
};

}  // namespace rangex::sim
