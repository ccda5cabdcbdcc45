#include "core/lane_config.h"

namespace rangex {

namespace {
// Appendix D (left camera) as calibrated, moved across the belt so that it sits over the
// lane centre.
LaneCamera appendix_d_camera() {
  Mat3 R;
  R.m = {0.9999830557535849,     -0.005375886795774679, -0.002233393579821996,
         -0.0021823579820766936, -0.7018696603759215,   0.7123020547193637,
         -0.005396806403924592,  -0.7122851112335202,   -0.7018694998329038};
  const Vec3 center{0.0, 414.54462853359297, 402.565204563682};
  return {"cam0",
          CameraModel({1780.10076, 894.26278, 319.5, 99.5, 0.0}, {-0.21403, -2.60592, 0, 0, 0}, R,
                      (R * center) * -1.0, 640, 200),
          {},
          ""};
}

// Appendix E (right camera) mirrored to the other side of the laser plane; the mirror flips
// the image's x axis so that the rotation stays proper (eq. 9-11 of the dissertation).
LaneCamera appendix_e_camera_mirrored() {
  Mat3 R;
  R.m = {0.9999325295453283,   -0.0031207014949952983, 0.011189172411761705,
         0.00543166590791716,  -0.7258369684221193,    -0.6878453258380488,
         0.010268074919173642, 0.6878596924474978,     -0.7257710452639232};
  const Vec3 center{0.0, -412.403598080687, 407.632237859188};
  return {"cam1",
          CameraModel({1803.65762, 902.53550, 319.5, 99.5, 0.0}, {-0.43360, 5.38559, 0, 0, 0}, R,
                      (R * center) * -1.0, 640, 200),
          {},
          ""};
}
}  // namespace

LaneConfig default_lane_config(int id) {
  LaneConfig c;
  c.id = id;
  c.cameras = {appendix_d_camera(), appendix_e_camera_mirrored()};
  c.xray.pixels = 480;
  c.xray.first_pixel_x_mm = -95.8;
  return c;
}

std::string unfitted_constants(const LaneConfig& l) {
  std::string what;
  auto add = [&](const std::string& s) { what += (what.empty() ? "" : "; ") + s; };
  for (int c = 0; c < 2; ++c) {
    const std::string& f = l.cameras[c].scatter_fitted_on;
    if (f.empty() || f.rfind("shipped", 0) == 0)
      add("cam" + std::to_string(c) + " K1/K2 (" + (f.empty() ? "never fitted" : "shipped") +
          "; rangexctl calib scatter)");
  }
  if (l.xray.detector_sigma_px == 0 && l.xray.focal_spot_sigma_mm == 0)
    add("the detector's blur (calib xray; the pseudo-X-ray is not matched at edges)");
  if (l.xray.measured_delay_lines == 0)
    add("the laser-to-X-ray registration (calib registration; whole lines only)");
  return what.empty() ? ""
                      : "lane " + std::to_string(l.id) +
                            " runs on constants never fitted on its own rig: " + what;
}

const char* trigger_name(LineTrigger t) {
  return t == LineTrigger::kFreeRun ? "free_run" : "encoder";
}

}  // namespace rangex
