// X-ray fan-beam calibration: the dissertation's real pin measurements (Table 9) and a
// simulated pin phantom with known geometry and blur.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "calib/fan_beam_fit.h"
#include "calib/pin_shadows.h"
#include "calib/xray_blur.h"
#include "core/error.h"
#include "sim/calib_scenes.h"

namespace rangex {
namespace {

std::vector<PinObservation> table9() {
  std::ifstream in(std::string(RANGEX_SOURCE_DIR) + "/tests/data/table9_pins.csv");
  std::vector<PinObservation> pins;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || line[0] == 'x') continue;
    std::istringstream ss(line);
    PinObservation o;
    char c;
    ss >> o.x_mm >> c >> o.z_mm >> c >> o.pixel;
    o.name = "L " + std::to_string(int(o.x_mm)) + " H " + std::to_string(int(o.z_mm));
    pins.push_back(o);
  }
  return pins;
}

FanBeam table9_start() {
  FanBeam fb;  // a generic start: source far above, detector below, 0.4 mm pixels held
  fb.pixels = 480;
  fb.source_x_mm = 80;
  fb.source_z_mm = 1000;
  fb.detector_z_mm = -100;
  fb.first_pixel_x_mm = 0;
  fb.pitch_mm = 0.4;
  return fb;
}

TEST(FanBeamTable9, FullModelFitsAtLeastAsWellAsAPlainFanBeam) {
  const auto pins = table9();
  ASSERT_EQ(pins.size(), 112u);
  FanBeamSolveOptions plain;
  plain.start = table9_start();
  plain.fit_pitch = false;  // detector units: the pitch is the gauge
  plain.fit_tilt = false;
  plain.huber_px = 0;
  const FanBeamFit p = fit_fan_beam(pins, plain);
  FanBeamSolveOptions full = plain;
  full.fit_tilt = true;
  full.row_offsets = true;
  full.huber_px = 1.0;
  const FanBeamFit f = fit_fan_beam(pins, full);
  std::printf(
      "Table 9: plain fan beam RMS %.3f worst %.3f; with tilt and row offsets RMS %.3f worst %.3f "
      "(detector units); source (%.1f, %.1f) detector z %.1f tilt %.3f deg\n",
      p.rms_px, p.worst_px, f.rms_px, f.worst_px, f.beam.source_x_mm, f.beam.source_z_mm,
      f.beam.detector_z_mm, f.beam.tilt_deg);
  EXPECT_TRUE(f.converged);
  EXPECT_LE(f.rms_px, p.rms_px + 1e-9);
  EXPECT_LE(f.worst_px, p.worst_px + 1e-9);
  // Every free parameter has a standard deviation.
  for (const Estimate& e : f.estimates)
    if (e.name != "pitch_mm") EXPECT_GT(e.stddev, 0) << e.name;
}

// A rig whose fan beam differs from plant.yaml: source moved, detector shifted and tilted.
LaneConfig perturbed_xray_rig() {
  LaneConfig rig = default_lane_config(0);
  rig.xray.source_x_mm += 3.0;
  rig.xray.source_z_mm += 12.0;
  rig.xray.first_pixel_x_mm -= 1.2;
  rig.xray.tilt_deg = 0.3;
  return rig;
}

std::vector<uint16_t> scan_phantom(const LaneConfig& rig, const PinPhantom& ph,
                                   const sim::XrayOptics& optics, int64_t* lines) {
  const sim::CalibScene scene = sim::pin_phantom_scene(ph);
  const sim::CalibXrayRenderer xr(rig, optics);
  const double step = rig.encoder_step_mm;
  *lines = int64_t((scene.end_b() + xr.plane_y(0, 0) + 30) / step);
  std::vector<uint16_t> x(size_t(*lines) * rig.xray.pixels);
  for (int64_t n = 0; n < *lines; ++n) {
    sim::Rng rng(5, n);
    xr.render(scene, double(n) * step, rng, &x[size_t(n) * rig.xray.pixels]);
  }
  return x;
}

TEST(FanBeamSimulated, PinPhantomRecoversGeometryAndBlur) {
  const LaneConfig nominal = default_lane_config(0);
  const LaneConfig rig = perturbed_xray_rig();
  sim::XrayOptics optics;
  optics.detector_sigma_px = 0.6;
  optics.focal_spot_sigma_mm = 0.8;
  const PinPhantom ph = PinPhantom::figure27();
  int64_t lines = 0;
  const auto x = scan_phantom(rig, ph, optics, &lines);
  const auto shadows = measure_pin_shadows(x.data(), lines, rig.xray.pixels, ph, nominal.xray);
  ASSERT_EQ(shadows.size(), 135u);
  std::vector<PinObservation> obs;
  for (const auto& s : shadows) obs.push_back(s.at);
  FanBeamSolveOptions o;
  o.start = nominal.xray;
  const FanBeamFit f = fit_fan_beam(obs, o);
  const FanBeam& t = rig.xray;
  std::printf(
      "simulated pins: RMS %.4f px worst %.4f px; source x %+.3f z %+.3f mm, first "
      "pixel %+.3f mm, pitch %+.5f mm, tilt %+.4f deg (fit - truth)\n",
      f.rms_px, f.worst_px, f.beam.source_x_mm - t.source_x_mm, f.beam.source_z_mm - t.source_z_mm,
      f.beam.first_pixel_x_mm - t.first_pixel_x_mm, f.beam.pitch_mm - t.pitch_mm,
      f.beam.tilt_deg - t.tilt_deg);
  EXPECT_LT(std::abs(f.beam.source_x_mm - t.source_x_mm), 0.2);
  EXPECT_LT(std::abs(f.beam.source_z_mm - t.source_z_mm), 0.2);
  EXPECT_LT(std::abs(f.beam.first_pixel_x_mm - t.first_pixel_x_mm), 0.2);
  // The far end of the detector, where pitch and tilt errors add up.
  const int last = t.pixels - 1;
  EXPECT_LT(
      std::hypot(f.beam.pixel_x(last) - t.pixel_x(last), f.beam.pixel_z(last) - t.pixel_z(last)),
      0.2);
  const XrayBlurFit b = fit_xray_blur(shadows, f.beam);
  std::printf(
      "blur: detector %.3f px (truth %.3f, std %.3f), focal spot %.3f mm (truth %.3f, "
      "std %.3f)\n",
      b.detector_sigma_px, optics.detector_sigma_px, b.detector_std, b.focal_spot_sigma_mm,
      optics.focal_spot_sigma_mm, b.focal_spot_std);
  EXPECT_NEAR(b.detector_sigma_px, optics.detector_sigma_px, 0.05);
  // The focal spot shows only in the highest pins' penumbra: held to its own precision.
  EXPECT_NEAR(b.focal_spot_sigma_mm, optics.focal_spot_sigma_mm, 3 * b.focal_spot_std);
}

TEST(FanBeamSimulated, APinOutOfViewIsNamed) {
  const LaneConfig nominal = default_lane_config(0);
  PinPhantom ph = PinPhantom::figure27();
  ph.rows[2].x_mm.push_back(120);  // beyond the 192 mm detector
  std::vector<uint16_t> x(480 * 100, 3600);
  try {
    measure_pin_shadows(x.data(), 100, 480, ph, nominal.xray);
    FAIL() << "a pin outside the detector was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("x 120 mm in row 2"), std::string::npos) << e.what();
  }
}

TEST(FanBeamSimulated, AMissingRowIsNamed) {
  const LaneConfig rig = default_lane_config(0);
  PinPhantom ph = PinPhantom::figure27();
  int64_t lines = 0;
  PinPhantom scanned = ph;
  scanned.rows.pop_back();  // one row fell out of the fixture
  const auto x = scan_phantom(rig, scanned, {}, &lines);
  try {
    measure_pin_shadows(x.data(), lines, 480, ph, rig.xray);
    FAIL() << "a missing row was not noticed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("8 rows"), std::string::npos) << e.what();
  }
}

TEST(FanBeamErrors, BadPinsAreNamed) {
  auto pins = table9();
  FanBeamSolveOptions o;
  o.start = table9_start();
  o.fit_pitch = false;
  pins[7].pixel = std::nan("");
  try {
    fit_fan_beam(pins, o);
    FAIL() << "NaN accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(pins[7].name), std::string::npos) << e.what();
  }
  pins = table9();
  for (auto& p : pins) p.z_mm = 30;
  EXPECT_THROW(fit_fan_beam(pins, o), Error);  // one height: source height undetermined
  pins = table9();
  pins.resize(4);
  EXPECT_THROW(fit_fan_beam(pins, o), Error);
}

}  // namespace
}  // namespace rangex
