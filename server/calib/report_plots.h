// Small PNG plots for the calibration reports (no plotting library: points and axes drawn
// into an RGB raster): residuals across the sensor, per-step height errors (Table 5), pin
// residuals along the detector.
#pragma once
#include <string>
#include <vector>

namespace rangex {

struct Series {
  std::vector<double> x, y;
  unsigned char r = 200, g = 30, b = 30;  // colour
};

// Points of every series in [x0, x1] x [y0, y1] (y up), with a frame, a zero line when 0
// lies inside, and grid lines every `grid_x` / `grid_y` units (0: none).
void plot_points(const std::string& path, const std::vector<Series>& series, double x0, double x1,
                 double y0, double y1, double grid_x = 0, double grid_y = 0, int width = 640,
                 int height = 240);

}  // namespace rangex
