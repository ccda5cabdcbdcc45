// A dual-energy step-wedge scan as the calibration takes it (docs/dual-energy.md): a wedge of
// a soft-tissue-equivalent plastic crossed with one of aluminium, scanned on the
// belt; per step its known thicknesses and its readings' mean and variance in each layer.
#pragma once
#include <string>
#include <vector>

namespace rangex {

struct WedgeStep {
  double a150_mm = 0, al_mm = 0;     // known
  double low = 0, high = 0;          // mean readings, DN
  double var_low = 0, var_high = 0;  // their variances over the step's pixels, DN^2
  int samples = 0;
};

struct WedgeScan {
  double open_low = 0, open_high = 0;  // the bare belt's readings
  std::vector<WedgeStep> steps;
};

// How the wedge lies on the belt in a scan (its drawing, wedge.yaml): the A-150 steps side
// by side across the detector, `step_pixels` each from `first_pixel`; the aluminium steps one
// after another along the belt, `step_lines` each, after `open_lines` of bare belt. A step
// is read as its flat middle, `margin_pixels` and `margin_lines` in from its edges.
struct WedgeLayout {
  std::vector<double> a150_mm = {0, 5, 10, 15, 20, 25, 30, 35, 40, 45, 50, 55, 60};
  std::vector<double> al_mm = {0, 1, 2, 3, 4, 5, 6};
  int first_pixel = 40, step_pixels = 30, margin_pixels = 4;
  int open_lines = 200, step_lines = 2500, margin_lines = 20;

  int lines() const { return open_lines + step_lines * int(al_mm.size()); }
  int last_pixel() const { return first_pixel + step_pixels * int(a150_mm.size()); }  // past end
};

}  // namespace rangex
