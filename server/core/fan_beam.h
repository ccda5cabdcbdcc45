// X-ray fan-beam geometry of one lane: a point source above the belt and a line detector
// below it, both in the X-ray plane, which lies delay_lines encoder steps downstream of the
// laser plane and parallel to it.
#pragma once

namespace rangex {

struct FanBeam {
  int pixels = 512;
  double pitch_mm = 0.4;
  double first_pixel_x_mm = -102.2;  // centre of detector pixel 0
  double detector_z_mm = -15.0;      // detector surface below the belt
  double source_x_mm = 0.0;
  double source_z_mm = 700.0;  // focal spot above the belt
  int delay_lines = 50;        // X-ray plane offset from the laser plane, in encoder steps
  int bits = 12;

  double pixel_x(int i) const { return first_pixel_x_mm + pitch_mm * i; }
};

}  // namespace rangex
