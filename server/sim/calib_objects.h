// Calibration objects on the belt (Laser Range Imaging §6.4): CNC blocks (the staircase of Table 5,
// the registration blocks of §6.4.3) and steel pins held across the fan beam (Figure 27), in the
// object coordinates of LaneScene (x across, b along the belt). Their surfaces feed the camera
// renderer; their attenuation feeds CalibXrayRenderer.
#pragma once
#include <cmath>
#include <vector>

#include "core/vec.h"

namespace rangex::sim {

struct CalibBox {
  double x0, x1, b0, b1, z0, z1;  // mm, in the box's own frame
  double yaw_rad = 0;  // turned about the vertical through its centre (a block set askew)
  // Object point (x, b) in the box's own frame.
  void local(double x, double b, double& lx, double& lb) const {
    const double cx = 0.5 * (x0 + x1), cb = 0.5 * (b0 + b1);
    const double c = std::cos(yaw_rad), s = std::sin(yaw_rad);
    lx = cx + c * (x - cx) + s * (b - cb);
    lb = cb - s * (x - cx) + c * (b - cb);
  }
  bool covers(double x, double b) const {
    double lx, lb;
    local(x, b, lx, lb);
    return lx >= x0 && lx < x1 && lb >= b0 && lb < b1;
  }
  double mu_per_mm = 0.02;  // POM-like plastic at the X-ray's energy, per mm of path
};

// A steel pin running along the belt: its cross-section is a circle in the fan's plane.
struct CalibPin {
  double x, z, radius, b0, b1;  // mm
  double mu_per_mm = 0.5;       // steel
};

class CalibScene {
 public:
  std::vector<CalibBox> boxes;
  std::vector<CalibPin> pins;  // held in a transparent fixture: invisible to the laser

  float height(double x, double b) const;         // highest box top at (x, b), 0 on the belt
  void slice(double b, float* out, int n) const;  // as LaneScene::slice, box-filtered
  float max_height(double b_lo, double b_hi) const;
  bool is_meat(const Vec3&) const { return false; }  // machined metal barely scatters
  double scatter_scale(const Vec3&, double) const { return 1; }
  double end_b() const;
};

}  // namespace rangex::sim
