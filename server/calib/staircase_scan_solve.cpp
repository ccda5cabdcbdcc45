#include "calib/staircase_scan_solve.h"

#include <cmath>

#include "calib/report_plots.h"
#include "calib/scan_lines.h"

namespace rangex {

namespace {
RegistrationFit measure_registration(const RecordingReader& rec, int lane, const LaneConfig& lc,
                                     const RegistrationOptions& opt) {
  const BlockSet set = parse_block_set(read_scan_drawing(rec.dir(), "blocks.yaml"), "blocks.yaml");
  const auto r0 = scan_stripe_rows(rec, lane, 0, lc.stripe);
  const auto r1 = scan_stripe_rows(rec, lane, 1, lc.stripe);
  const auto x = scan_xray_lines(rec, lane);
  RegistrationScan scan;
  scan.rows[0] = r0.data(), scan.rows[1] = r1.data();
  scan.width = rec.info().width;
  scan.xray = x.data();
  scan.lines = rec.info().lines;
  return fit_registration(scan, lc.cameras[0].model, lc.cameras[1].model, lc.xray,
                          lc.encoder_step_mm, set, opt);
}
}  // namespace

StaircaseScanSolve solve_staircase_scan(const RecordingReader& rec, int lane, LaneConfig& lc,
                                        bool solve, const std::string& steps_png) {
  StaircaseScanSolve s;
  s.drawing = parse_staircase(read_scan_drawing(rec.dir(), "staircase.yaml"), "staircase.yaml");
  const Staircase& st = s.drawing;
  for (int cam = 0; cam < 2; ++cam) {
    const auto rows = scan_stripe_rows(rec, lane, cam, lc.stripe);
    s.fits[cam] = fit_staircase(rows.data(), rec.info().lines, rec.info().width,
                                lc.cameras[cam].model, st, "cam" + std::to_string(cam), solve);
    s.reports[cam] =
        s.fits[cam].report("lane " + std::to_string(lane) + " cam" + std::to_string(cam));
  }
  // Each step's error (mm, +-0.3 full scale) for cam0 (red) and cam1 (blue), beside the
  // drawing's height.
  Series c0{{}, {}, 210, 30, 30}, c1{{}, {}, 30, 60, 210};
  for (size_t k = 0; k < st.heights_mm.size(); ++k) {
    c0.x.push_back(st.heights_mm[k] - 0.6), c0.y.push_back(s.fits[0].steps[k].error_mm);
    c1.x.push_back(st.heights_mm[k] + 0.6), c1.y.push_back(s.fits[1].steps[k].error_mm);
  }
  plot_points(steps_png, {c0, c1}, 0, st.heights_mm.back() + 5, -0.3, 0.3, 5, 0.1, 480, 240);
  if (solve) {
    for (int cam = 0; cam < 2; ++cam) lc.cameras[cam].model = s.fits[cam].camera;
    lc.laser = LaserPlane{};  // the plane defines the frame: y = 0
  }
  return s;
}

RegistrationFit check_blocks_scan(const RecordingReader& rec, int lane, const LaneConfig& lc) {
  RegistrationOptions hold;
  hold.fit_offset = false, hold.solve_planes = false;
  const FanBeam& x = lc.xray;
  hold.delay_lines = x.measured_delay_lines != 0 ? x.measured_delay_lines : x.delay_lines;
  hold.alpha_deg = x.plane_alpha_deg, hold.beta_deg = x.plane_beta_deg;
  return measure_registration(rec, lane, lc, hold);
}

RegistrationFit solve_blocks_scan(const RecordingReader& rec, int lane, LaneConfig& lc) {
  const RegistrationFit f = measure_registration(rec, lane, lc, {});
  lc.cameras[0].model = f.cameras[0];
  lc.cameras[1].model = f.cameras[1];
  lc.xray.delay_lines = int(std::lround(f.delay_lines));
  lc.xray.measured_delay_lines = f.delay_lines;
  lc.xray.plane_alpha_deg = f.alpha_deg;
  lc.xray.plane_beta_deg = f.beta_deg;
  return f;
}

}  // namespace rangex
