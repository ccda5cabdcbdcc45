#include "calib/pin_phantom_solve.h"

#include <algorithm>
#include <fstream>
#include <sstream>

#include "calib/report_plots.h"
#include "calib/scan_lines.h"
#include "core/error.h"

namespace rangex {

std::vector<PinObservation> read_pin_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail(path, ": cannot open");
  std::vector<PinObservation> pins;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty() || line[0] == '#' || line[0] == 'x') continue;
    PinObservation o;
    char c1 = 0, c2 = 0;
    std::istringstream ss(line);
    if (!(ss >> o.x_mm >> c1 >> o.z_mm >> c2 >> o.pixel) || c1 != ',' || c2 != ',')
      fail(path, ":", n, ": expected x_mm,z_mm,pixel");
    o.name = join(path, ":", n);
    pins.push_back(o);
  }
  return pins;
}

std::vector<PinShadow> measure_scan_pins(const RecordingReader& rec, const FanBeam& start) {
  const PinPhantom ph =
      parse_pin_phantom(read_scan_drawing(rec.dir(), "pin_phantom.yaml"), "pin_phantom.yaml");
  const auto x = scan_xray_lines(rec, rec.info().lanes.at(0));
  return measure_pin_shadows(x.data(), rec.info().lines, rec.info().xray_pixels, ph, start);
}

PinPhantomSolve solve_pin_phantom(const std::vector<PinObservation>& pins,
                                  const std::vector<PinShadow>& shadows,
                                  const FanBeamSolveOptions& opt, int detector_pixels,
                                  const std::string& residuals_png) {
  PinPhantomSolve s;
  s.fit = fit_fan_beam(pins, opt);
  const FanBeamFit& f = s.fit;
  if (!residuals_png.empty()) {
    // Pin residuals along the detector (px, +-4 RMS full scale), one colour per row.
    std::vector<Series> rows;
    std::vector<double> heights;
    for (size_t i = 0; i < pins.size(); ++i) {
      const auto it = std::find(heights.begin(), heights.end(), pins[i].z_mm);
      const size_t k = size_t(it - heights.begin());
      if (it == heights.end()) {
        heights.push_back(pins[i].z_mm);
        rows.push_back({{},
                        {},
                        (unsigned char)(40 + 50 * (k % 4)),
                        (unsigned char)(30 * (k % 7)),
                        (unsigned char)(220 - 25 * (k % 8))});
      }
      rows[k].x.push_back(pins[i].pixel);
      rows[k].y.push_back(f.residual_px[i]);
    }
    const double span = std::max(4 * f.rms_px, 1e-3);
    plot_points(residuals_png, rows, 0, detector_pixels - 1, -span, span, 40, 0, 640, 240);
  }
  s.beam = f.beam;
  if (!shadows.empty()) {
    s.blur = fit_xray_blur(shadows, f.beam);
    s.beam.detector_sigma_px = s.blur->detector_sigma_px;
    s.beam.focal_spot_sigma_mm = s.blur->focal_spot_sigma_mm;
  }
  return s;
}

}  // namespace rangex
