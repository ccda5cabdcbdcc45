// A dual-energy step-wedge scan as the calibration takes it (docs/dual-energy.md): a wedge of
// a soft-tissue-equivalent plastic crossed with one of aluminium, scanned on the
// belt; per step its known thicknesses and its readings' mean and variance in each layer.
#pragma once
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

}  // namespace rangex
